"""A scene read as a tree of joints: the one reader of a scene's topology, for every adapter.

:func:`read_tree` grows a forest breadth-first from the particles a Pin, Line or
Ellipse holds (the roots), along the Rods; a constraint met a second time
closes a loop. It refuses nothing: each adapter decides what it can build from
the result (MuJoCo and Drake nest bodies along it, PyBullet builds its
multibodies from it, the reference integrates a chain in its angles) and says
why it cannot in its own words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engines.scene.scene import Pin, Rod, Scene

#: Tree.parent of a particle a Pin, Line or Ellipse holds (its joint is on the ground).
ROOT = -1
#: Tree.parent of a particle tied to no root (free-floating).
LOOSE = -2


@dataclass(frozen=True)
class Tree:
    """The constraints of a scene as a forest hung from its roots (Pins, Lines, Ellipses).

    parent : (n,) parent particle index, :data:`ROOT` for a particle held by a Pin, Line or Ellipse,
        :data:`LOOSE` for one tied to no root.
    pivot : (n, 3) m, the pivot of each particle's link at the initial state (the Pin's anchor, or the
        parent's initial position; a particle on a Line or Ellipse is its own pivot).
    constraint_of : (n,) index of the constraint joining the particle to its parent (−1 when loose).
    order : particles, parents before children (breadth-first; roots in constraint order).
    closures : constraints that close a loop (not joints of the tree), in increasing index.
    found : the same, in the order the reading met them (a second root on a particle first, in
        constraint order, then rods as the breadth-first walk meets them).
    """

    parent: tuple[int, ...]
    pivot: np.ndarray
    constraint_of: tuple[int, ...]
    order: tuple[int, ...]
    closures: tuple[int, ...] = ()
    found: tuple[int, ...] = ()

    @property
    def loose(self) -> list[int]:
        """Particles tied to no Pin, Line or Ellipse."""
        return [i for i, p in enumerate(self.parent) if p == LOOSE]

    def path(self) -> list[int] | None:
        """The particles from the root down when the tree is one unbranched chain hung from one root
        with no loop and nothing loose, else None."""
        if self.closures or self.loose or self.parent.count(ROOT) != 1:
            return None
        children = [0] * len(self.parent)
        for p in self.parent:
            if p >= 0:
                children[p] += 1
        return list(self.order) if max(children, default=0) <= 1 else None


def read_tree(scene: Scene) -> Tree:
    """The forest of ``scene`` grown from its roots; a constraint met twice closes a loop (see :class:`Tree`)."""
    n = len(scene.particles)
    q = scene.initial_positions
    parent, constraint_of = [LOOSE] * n, [-1] * n
    pivot = np.zeros((n, 3))
    neighbours: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    queue: list[int] = []
    closures: list[int] = []
    for k, c in enumerate(scene.constraints):
        if isinstance(c, Rod):
            neighbours[c.a].append((c.b, k))
            neighbours[c.b].append((c.a, k))
            continue
        if parent[c.particle] != LOOSE:
            closures.append(k)  # a second root on one particle closes a loop through the ground
            continue
        parent[c.particle], constraint_of[c.particle] = ROOT, k
        pivot[c.particle] = c.anchor if isinstance(c, Pin) else q[c.particle]
        queue.append(c.particle)
    order: list[int] = []
    head = 0
    while head < len(queue):
        i = queue[head]
        head += 1
        order.append(i)
        for j, k in neighbours[i]:
            if k == constraint_of[i] or k in closures:
                continue
            if parent[j] != LOOSE:
                closures.append(k)
                continue
            parent[j], constraint_of[j], pivot[j] = i, k, q[i]
            queue.append(j)
    return Tree(tuple(parent), pivot, tuple(constraint_of), tuple(order), tuple(sorted(closures)), tuple(closures))
