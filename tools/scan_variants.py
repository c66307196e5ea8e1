"""Variants of a scan that keep its surface and atlas but change how it is
stored, for tests and benchmarks that ask whether the layout depends on the
storage (bench/tessellation.py, python_tests/test_native.py).

Arrays as tools/scan_io.Scan holds them: positions (V, 3), triangles (F, 3),
uvs (F, 3, 2) per face corner, face_page (F,).
"""
from __future__ import annotations

import numpy as np


def split_in_four(positions: np.ndarray, triangles: np.ndarray, uvs: np.ndarray):
    """(positions, triangles, uvs) with every triangle split into four at its
    edges' midpoints, in 3D and in UV: the same surface and atlas,
    tessellated four times finer (face f becomes faces 4f .. 4f + 3)."""
    corners = np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=2).reshape(-1, 2)
    edges, edge_of = np.unique(np.sort(corners, axis=1), axis=0, return_inverse=True)
    mid = len(positions) + edge_of.reshape(-1, 3)  # per face: the midpoints of edges 01, 12, 20
    points = np.vstack([positions, positions[edges].mean(axis=1)])
    a, b, c = triangles.T
    ab, bc, ca = mid.T
    faces = np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))], axis=1)
    u0, u1, u2 = uvs[:, 0], uvs[:, 1], uvs[:, 2]
    m01, m12, m20 = (u0 + u1) / 2, (u1 + u2) / 2, (u2 + u0) / 2
    corner_uvs = np.stack([np.stack(t, axis=1) for t in ((u0, m01, m20), (m01, u1, m12), (m20, m12, u2),
                                                         (m01, m12, m20))], axis=1)
    return points, faces.reshape(-1, 3).astype(triangles.dtype), corner_uvs.reshape(-1, 3, 2)


def with_debris(positions: np.ndarray, triangles: np.ndarray, uvs: np.ndarray, face_page: np.ndarray,
                count: int, seed: int = 1):
    """(positions, triangles, uvs, face_page) with `count` loose triangles
    added, as phone scans keep fragments: each a few thousandths of the
    model's size beside a vertex of it, on its own small spot of page 0."""
    rng = np.random.default_rng(seed)
    span = float(np.ptp(positions, axis=0).max())
    corners = positions[rng.integers(0, len(positions), count)][:, None, :]
    corners = corners + rng.normal(scale=0.002 * span, size=(count, 3, 3))
    loose = len(positions) + np.arange(3 * count).reshape(-1, 3)
    spots = rng.random((count, 1, 2)) * 0.9 + 0.05 + rng.random((count, 3, 2)) * 0.004
    return (np.vstack([positions, corners.reshape(-1, 3)]), np.vstack([triangles, loose]).astype(triangles.dtype),
            np.concatenate([uvs, spots]), np.concatenate([face_page, np.zeros(count, face_page.dtype)]))
