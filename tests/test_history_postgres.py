"""The history store on a real PostgreSQL server, started here from Debian's binaries and stopped after.

The server is a throwaway cluster (initdb) in a temporary directory,
listening on 127.0.0.1 at a free port, with trust authentication and fsync
off (nothing in it outlives the test). PostgreSQL refuses to run as root,
so under root the cluster belongs to the ``postgres`` user the Debian
package creates (``nobody`` otherwise). Skipped, with the reason, only when
the server binaries or the ``postgres`` extra (SQLAlchemy, psycopg) are not
installed; .ci/run installs both.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

import pytest

from compare.gate.baseline import build_baseline
from compare.history.store import AlreadyRecorded, History, HistoryError
from compare.history.window import window_baseline

from ci_mode import postgres_binaries
from history_support import ENGINE, add_in_process, ERRORS, add, real_run, synthetic, xval


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="module")
def server():
    """A running PostgreSQL server: yields its URL (database ``postgres``, user ``xval``); stopped and removed after."""
    pytest.importorskip("sqlalchemy", reason="the postgres extra is not installed: pip install 'xval[postgres]'")
    pytest.importorskip("psycopg", reason="the postgres extra is not installed: pip install 'xval[postgres]'")
    binaries = postgres_binaries()
    if binaries is None:
        pytest.skip("PostgreSQL server binaries (initdb, pg_ctl) not installed: apt-get install postgresql")
    user = None
    if os.geteuid() == 0:
        for name in ("postgres", "nobody"):
            try:
                user = pwd.getpwnam(name)
                break
            except KeyError:
                continue
        if user is None:
            pytest.skip("running as root and no 'postgres' or 'nobody' user to run the server as")
    root = Path(tempfile.mkdtemp(prefix="xval-pg-"))
    data, log = root / "data", root / "server.log"
    if user is not None:
        os.chown(root, user.pw_uid, user.pw_gid)
    as_user = {"user": user.pw_uid, "group": user.pw_gid} if user is not None else {}
    port = free_port()

    def run(*argv: str) -> None:
        done = subprocess.run([str(binaries / argv[0]), *argv[1:]], capture_output=True, text=True, timeout=120,
                              cwd=root, **as_user)
        if done.returncode != 0:
            raise RuntimeError(f"{argv[0]} failed: {done.stderr or done.stdout}")

    try:
        run("initdb", "-D", str(data), "-U", "xval", "--auth=trust", "-E", "UTF8", "--no-sync")
        options = f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off -c full_page_writes=off"
        run("pg_ctl", "-D", str(data), "-o", options, "-l", str(log), "-w", "-t", "60", "start")
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)
        raise
    try:
        yield f"postgresql://xval@127.0.0.1:{port}/postgres"
    finally:
        try:
            run("pg_ctl", "-D", str(data), "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return real_run(tmp_path_factory.mktemp("history-pg") / "run")


@pytest.fixture
def url(server):
    """The server with a fresh schema per test (the tables of one test never meet another's)."""
    import sqlalchemy

    schema = f"t{os.getpid()}_{next(_counter)}"
    engine = sqlalchemy.create_engine(server.replace("postgresql://", "postgresql+psycopg://"))
    with engine.begin() as connection:
        connection.execute(sqlalchemy.text(f"CREATE SCHEMA {schema}"))
    engine.dispose()
    return f"{server}?options=-csearch_path%3D{schema}"


_counter = iter(range(10**6))


def test_round_trip_append_only_and_a_run_added_once(base, url):
    with History.open(url, create=True) as history:
        first = add(history, base, 0)
        add(history, synthetic(base, 1, error=2.0), 1)
        assert "postgresql+psycopg://xval@127.0.0.1" in history.name
        stored = {c.case_key: c for c in history.cases([first.id])}
        assert dict(build_baseline(base).cases) == {k: c.entry for k, c in stored.items()}
        key = next(iter(stored))
        assert history.record(first.id, key).to_json() in [r.to_json() for r in base.records]
        with pytest.raises(AlreadyRecorded, match=r"already in the history .* as run 1 \(added [^)]+\); not added again"):
            history.add(base, first.origin)
        import sqlalchemy

        with pytest.raises(sqlalchemy.exc.DBAPIError, match="append-only"):
            with history.backend.engine.begin() as connection:
                connection.execute(sqlalchemy.text("UPDATE xval_runs SET commit_sha = 'x'"))
        assert [r.id for r in history.runs()] == [1, 2] and history.run(1) == first


def test_writers_at_once_all_land_even_when_creating_the_tables(base, url):
    context = multiprocessing.get_context("fork")
    barrier = context.Manager().Barrier(3)
    with context.Pool(3) as pool:
        ids = pool.starmap(add_in_process, [(url, str(base.path), i, barrier) for i in range(3)])
    assert sorted(ids) == [1, 2, 3]
    with History.open(url) as history:
        assert len(history.cases()) == 18


def test_the_commands_take_a_postgresql_url(base, url, tmp_path, capsys):
    code, out, err = xval(capsys, "history", "add", base.path, "--history", url)
    assert code == 0 and "run 1 added: suite gate-test, 6 cases" in out, err
    code, out, _ = xval(capsys, "history", "show", "--history", url, "--format", "json", "--metric", "energy_drift")
    assert code == 0 and len(json.loads(out)) == 6
    code, out, _ = xval(capsys, "gate", base.path, "--history", url, "--timing", "report")
    assert code == 0 and "no earlier run of suite 'gate-test' on this machine" in out  # the run itself is left out
    code, out, _ = xval(capsys, "history", "report", "--history", url, "--output", tmp_path / "trend.html")
    assert code == 0 and "(1 runs, 0 step changes" in out


def test_the_windowed_gate_reads_the_same_from_postgresql(base, url):
    with History.open(url, create=True) as history:
        for index in range(3):
            add(history, synthetic(base, index, error=1.0 + 0.5 * index), index)
        window = window_baseline(history, synthetic(base, 9), 3)
    assert [r.id for r in window.runs] == [1, 2, 3]
    best = build_baseline(base).cases
    for key, entry in window.document.cases.items():
        for metric in ERRORS:  # the best of 1×, 1.5×, 2× is 1×
            assert entry.metric(metric) == best[key].metric(metric)
    assert any(e.engine == ENGINE for e in window.document.cases.values())


def test_an_unreachable_server_is_one_clear_error():
    pytest.importorskip("sqlalchemy", reason="the postgres extra is not installed: pip install 'xval[postgres]'")
    with pytest.raises(HistoryError, match=r"postgresql\+psycopg://xval:\*\*\*@127.0.0.1:1/x: cannot use the history database"):
        History.open("postgresql://xval:secret@127.0.0.1:1/x")
