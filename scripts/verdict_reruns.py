"""Do reruns give the same verdict? Per scene, each run's winners, ties and ratio interval from `xval verdict --format json`.

    .venv/bin/python scripts/verdict_reruns.py RESULTS_DIR RESULTS_DIR [...]

Runs `xval verdict DIR --format json` on each directory (the same document users get) and prints, per scene
and run, the focus family's winner with its ties, the best other engine with its ties, and the cost ratio
with its interval; then whether the winners agree and every pair of ratio intervals overlaps.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

XVAL = [sys.executable, "-c", "from compare.cli import main; main()"]


def document(directory: str) -> dict:
    out = subprocess.run([*XVAL, "verdict", directory, "--format", "json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main(directories: list[str]) -> None:
    documents = [document(d) for d in directories]
    for k, scene in enumerate(documents[0]["scenes"]):
        print(f"{scene['scene']}:")
        rows = []
        for directory, doc in zip(directories, documents):
            c = doc["scenes"][k]["comparison"]
            if c is None:  # no second family on this scene to compare with
                rows.append((set(), set(), None, None))
                print(f"  {Path(directory).name}: no comparison")
                continue
            low, high = c["ratio_interval"] or (None, None)
            winners = {c["focus"], *c["focus_ties"]}
            others = {c["other"], *c["other_ties"]}
            rows.append((winners, others, low, high))
            # No ratio when one side never reaches the accuracy (a plateau, or no ok points).
            ratio = "none" if c["ratio"] is None else f"{c['ratio']:.3g} [{low:.3g}, {high:.3g}]"
            print(f"  {Path(directory).name}: {c['focus']} (ties: {', '.join(c['focus_ties']) or 'none'}) vs "
                  f"{c['other']} (ties: {', '.join(c['other_ties']) or 'none'}); ratio {ratio}"
                  f"{' tie' if c['tie'] else ''}")
        shared = set.intersection(*(w for w, _, _, _ in rows))
        bounded = [r for r in rows if r[2] is not None]
        overlap = all(a[2] <= b[3] and b[2] <= a[3] for a in bounded for b in bounded)
        print(f"  winner named in every run: {', '.join(sorted(shared)) or 'none'}; "
              f"other side the same: {len({frozenset(o) for _, o, _, _ in rows}) == 1}; ratio intervals overlap: {overlap}")


if __name__ == "__main__":
    main(sys.argv[1:])
