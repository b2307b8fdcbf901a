"""The layered roadmap of docs/model.md §12 as one sparse matrix.

Nodes
-----
- ``a * N + z`` for every configuration z and angle index a (the robot at z whose current
  bouncing angle is Φ[a]); m * N of them;
- ``m * N + z``: a *start* node per configuration. The robot may start with any angle, so the
  start node carries, for each out-edge of the layer nodes (z, a), the cheapest of them.
  Then ``dist(start(z), v) = min_a dist((z, a), v)`` for every v reached by at least one edge,
  and one single-source search per start answers "minimum over start layers".

Edges
-----
- forward step (z, a) -> (z', a), weight w1;
- bump at z: (z, a) -> (rot(z, Φ[b]), b), weight w1 when b == a else w2;
- start(z) -> the same targets, weight min over a (w1 forward; min(w1, w2) for a bump).

Every edge either moves to another position cell with the same heading (label 0) or stays in
its cell and turns (label Φ[layer of the target]), so an edge's label is read off its ends.

Examples
--------
>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> env = Environment.from_dict({"boundary": [[0, 0], [0.68, 0], [0.68, 0.34], [0, 0.34]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> rm = Roadmap(CellSpace(env), [90, 180])
>>> rm.n_nodes, rm.graph.nnz          # 2 layers x 8 configs + 8 start nodes
(24, 44)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from envs import UserError

from ..cells import CellSpace

__all__ = ["Roadmap"]


@dataclass(frozen=True, eq=False)
class Roadmap:
    """Layered roadmap over configurations and bouncing angles (docs/model.md §12).

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float
        The bouncing angles Φ [deg], multiples of 360°/K, no duplicates.
    w1, w2 : float
        Weight of a step or a same-angle bump (w1), and of a bump that changes angle (w2).
    """

    cells: CellSpace
    angles: tuple
    w1: float = 1.0
    w2: float = 100.0

    def __post_init__(self) -> None:
        angles = tuple(float(a) for a in self.angles)
        if not angles:
            raise UserError("the roadmap needs at least one bouncing angle.")
        steps = [self.cells.angle_steps(a) for a in angles]
        if len(set(steps)) != len(steps):
            raise UserError(f"the bouncing angles {list(angles)} repeat an angle.")
        for name, w in (("w1", self.w1), ("w2", self.w2)):
            if not (np.isfinite(w) and w > 0):
                raise UserError(f"{name} must be a positive number, got {w}.")
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "_steps", np.asarray(steps, dtype=np.int64))

    # ------------------------------------------------------------------ sizes
    @property
    def m(self) -> int:
        """Number of bouncing angles."""
        return len(self.angles)

    @property
    def N(self) -> int:
        """Number of configurations."""
        return self.cells.N

    @property
    def n_nodes(self) -> int:
        """Nodes of the roadmap: m layers of N, plus N start nodes."""
        return (self.m + 1) * self.N

    def start_node(self, z):
        """The start node of configuration(s) ``z``."""
        return self.m * self.N + np.asarray(z)

    def node(self, z, a):
        """The node of configuration(s) ``z`` in angle layer(s) ``a``."""
        return np.asarray(a) * self.N + np.asarray(z)

    def config_of(self, node):
        """Configuration z of a node (layer or start node)."""
        return np.asarray(node) % self.N

    def layer_of(self, node):
        """Angle index of a node (m for start nodes)."""
        return np.asarray(node) // self.N

    # ------------------------------------------------------------------ graph
    @cached_property
    def rotated(self) -> np.ndarray:
        """(m, N) array: configuration after a bump at z with angle Φ[b]."""
        return self.cells.turn(np.arange(self.N)[None, :], self._steps[:, None])

    @cached_property
    def graph(self) -> sp.csr_matrix:
        """The roadmap as a CSR matrix of edge weights (n_nodes x n_nodes)."""
        N, m, w1, w2 = self.N, self.m, float(self.w1), float(self.w2)
        fwd = self.cells.forward
        fz = np.nonzero(fwd >= 0)[0]
        bz = np.nonzero(fwd < 0)[0]
        rows, cols, vals = [], [], []
        layers = np.arange(m)
        # forward steps (z, a) -> (z', a) in every layer
        rows.append((layers[:, None] * N + fz[None, :]).ravel())
        cols.append((layers[:, None] * N + fwd[fz][None, :]).ravel())
        vals.append(np.full(rows[-1].shape, w1))
        # a start node steps forward into every layer
        rows.append(np.tile(m * N + fz, m))
        cols.append((layers[:, None] * N + fwd[fz][None, :]).ravel())
        vals.append(np.full(rows[-1].shape, w1))
        # bumps: (z, a) -> (rot_b(z), b)
        a_idx, b_idx = np.meshgrid(layers, layers, indexing="ij")      # (m, m)
        rows.append((a_idx[:, :, None] * N + bz[None, None, :]).ravel())
        cols.append((b_idx[:, :, None] * N + self.rotated[:, bz][None, :, :]).ravel())
        wts = np.where(a_idx == b_idx, w1, w2)
        vals.append(np.broadcast_to(wts[:, :, None], (m, m, len(bz))).ravel())
        # bumps from the start nodes: the cheapest start layer, min(w1, w2) when m > 1
        rows.append(np.tile(m * N + bz, m))
        cols.append((layers[:, None] * N + self.rotated[:, bz]).ravel())
        vals.append(np.full(rows[-1].shape, w1 if m == 1 else min(w1, w2)))
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        v = np.concatenate(vals)
        return sp.csr_matrix((v, (r, c)), shape=(self.n_nodes, self.n_nodes))

    def labels_of_path(self, nodes) -> list:
        """Observation labels along a node path: 0 for a step, Φ[layer] for a bump."""
        nodes = np.asarray(nodes)
        if len(nodes) < 2:
            return []
        P = self.cells.P
        conf = self.config_of(nodes)
        same_cell = (conf[1:] % P) == (conf[:-1] % P)
        layer = self.layer_of(nodes[1:])
        return [self.angles[b] if bump else 0 for bump, b in zip(same_cell, layer)]
