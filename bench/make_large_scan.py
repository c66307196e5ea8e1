"""Generates a large, fragmented, photogrammetry-like scan for the benchmark.

    .venv/bin/python bench/make_large_scan.py [--out bench/.cache] [--force]

A closed lumpy blob (a cube-sphere displaced by a smooth random radius,
1,009,200 triangles at the default --grid 290), its surface cut into ~15,000
small charts grown from random seed faces over the face graph, each chart
flattened by projection onto its mean normal, all at one texel density and
shelf-packed into one 8192 x 8192 page, and a texture with detail baked into
that atlas: a smooth colour field of the 3D position plus value noise a few
texels wide, with a 1.5-texel gutter around every chart.

Writes <out>/large_scan/large_scan.obj + .mtl + _color.png and meta.json. It is
deterministic (seeded) and skips the work when meta.json says the same
parameters were already written. numpy and Pillow only.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

GENERATOR_VERSION = 1
HERE = Path(__file__).resolve().parent


def log(msg: str) -> None:
    print(f"[make_large_scan] {msg}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------- mesh
def cube_sphere(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions and outward triangles of a cube-sphere with n x n cells per cube face."""
    if n % 2:
        raise ValueError("grid must be even")
    h = n // 2
    side = n + 1
    ii, jj = np.meshgrid(np.arange(side) - h, np.arange(side) - h, indexing="ij")
    r, c = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v00 = (r * side + c).ravel()
    v10, v01, v11 = v00 + side, v00 + 1, v00 + side + 1
    cell_tris = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    points, tris = [], []
    for k, (axis, sign) in enumerate([(a, s) for a in range(3) for s in (-1, 1)]):
        p = np.empty((side * side, 3), dtype=np.int64)
        p[:, axis] = sign * h
        p[:, (axis + 1) % 3] = ii.ravel()
        p[:, (axis + 2) % 3] = jj.ravel()
        points.append(p)
        tris.append(cell_tris + k * side * side)
    points = np.concatenate(points)
    tris = np.concatenate(tris)
    key = ((points[:, 0] + h) * side + (points[:, 1] + h)) * side + (points[:, 2] + h)
    uniq, inverse = np.unique(key, return_inverse=True)
    tris = inverse[tris]
    grid = np.stack([uniq // (side * side), (uniq // side) % side, uniq % side], 1) - h
    cube = np.tan(grid / h * (np.pi / 4))  # spreads the cells evenly over the sphere
    dirs = cube / np.linalg.norm(cube, axis=1, keepdims=True)
    return dirs, tris.astype(np.int64)


def displace(dirs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A star-shaped blob: radius is 1 plus a sum of smooth waves over the direction."""
    radius = np.ones(len(dirs))
    for _ in range(12):
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        freq = rng.uniform(1.5, 8.0)
        radius += (0.09 / freq ** 0.8) * np.sin(freq * (dirs @ w) + rng.uniform(0, 2 * np.pi))
    pos = dirs * radius[:, None]
    pos *= np.array([0.6, 0.45, 0.4])  # metres, elongated like a rock
    return pos


def orient_outward(pos: np.ndarray, tris: np.ndarray) -> np.ndarray:
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    n = np.cross(b - a, c - a)
    flip = np.einsum("ij,ij->i", n, (a + b + c)) < 0
    tris = tris.copy()
    tris[flip] = tris[flip][:, [0, 2, 1]]
    return tris


def face_adjacency(tris: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Both directions of every face pair sharing an edge."""
    f = len(tris)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e.sort(axis=1)
    key = e[:, 0] * n_vertices + e[:, 1]
    face = np.tile(np.arange(f), 3)
    order = np.argsort(key, kind="stable")
    key, face = key[order], face[order]
    same = np.nonzero(key[1:] == key[:-1])[0]
    a, b = face[same], face[same + 1]
    return np.concatenate([a, b]), np.concatenate([b, a])


def grow_charts(n_faces: int, adj: tuple[np.ndarray, np.ndarray], n_charts: int,
                rng: np.random.Generator) -> np.ndarray:
    """Multi-source breadth-first growth from random seed faces (graph Voronoi regions)."""
    src, dst = adj
    label = np.full(n_faces, -1, dtype=np.int64)
    seeds = rng.choice(n_faces, size=n_charts, replace=False)
    label[seeds] = np.arange(n_charts)
    while True:
        grow = (label[src] >= 0) & (label[dst] < 0)
        if not grow.any():
            break
        label[dst[grow]] = label[src[grow]]
    if (label < 0).any():  # faces in components without a seed
        rest = np.nonzero(label < 0)[0]
        label[rest] = n_charts + np.arange(len(rest))
    return label


# ---------------------------------------------------------------- atlas
def flatten_charts(pos, tris, label):
    """Per-corner 2D coordinates (metres): projection on each chart's mean normal, PCA-aligned."""
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    fn = np.cross(b - a, c - a)  # length = 2 * area
    n_l = int(label.max()) + 1
    mean_n = np.stack([np.bincount(label, fn[:, k], n_l) for k in range(3)], 1)
    mean_n /= np.maximum(np.linalg.norm(mean_n, axis=1, keepdims=True), 1e-30)
    # Faces turned away from their chart's normal would fold over: give each its own chart.
    unit_fn = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-30)
    bad = np.einsum("ij,ij->i", unit_fn, mean_n[label]) < 0.25
    if bad.any():
        label = label.copy()
        label[bad] = n_l + np.arange(int(bad.sum()))
        mean_n = np.concatenate([mean_n, unit_fn[bad]])
        n_l = len(mean_n)
    # Tangent frame per chart.
    helper = np.where(np.abs(mean_n[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(mean_n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(mean_n, t1)
    corner_chart = np.repeat(label, 3)
    corners = pos[tris.reshape(-1)]
    uv = np.stack([np.einsum("ij,ij->i", corners, t1[corner_chart]),
                   np.einsum("ij,ij->i", corners, t2[corner_chart])], 1)
    # Rotate each chart to its principal axes so its bounding box is tight.
    cnt = np.bincount(corner_chart, minlength=n_l).astype(np.float64)
    cnt = np.maximum(cnt, 1)
    mu = np.stack([np.bincount(corner_chart, uv[:, k], n_l) / cnt for k in range(2)], 1)
    d = uv - mu[corner_chart]
    cxx = np.bincount(corner_chart, d[:, 0] * d[:, 0], n_l)
    cyy = np.bincount(corner_chart, d[:, 1] * d[:, 1], n_l)
    cxy = np.bincount(corner_chart, d[:, 0] * d[:, 1], n_l)
    ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)
    ca, sa = np.cos(ang)[corner_chart], np.sin(ang)[corner_chart]
    uv = np.stack([ca * d[:, 0] + sa * d[:, 1], -sa * d[:, 0] + ca * d[:, 1]], 1)
    return uv.reshape(-1, 3, 2), label


def shelf_pack(w: np.ndarray, h: np.ndarray, page: int):
    """Offsets of boxes (w, h) packed in shelves, tallest first; None if they do not fit."""
    order = np.lexsort((-w, -h))
    x = np.zeros(len(w), dtype=np.int64)
    y = np.zeros(len(w), dtype=np.int64)
    cx = cy = shelf = 0
    for i in order:
        wi, hi = int(w[i]), int(h[i])
        if cx + wi > page:
            cy += shelf
            cx = shelf = 0
        if wi > page or cy + hi > page:
            return None
        x[i], y[i] = cx, cy
        cx += wi
        shelf = max(shelf, hi)
    return x, y


def pack_atlas(uv_m: np.ndarray, label: np.ndarray, page: int, pad: int):
    """Scales all charts by one texel density (the largest that fits) and packs them."""
    n_l = int(label.max()) + 1
    corner_chart = np.repeat(label, 3)
    flat = uv_m.reshape(-1, 2)
    order = np.argsort(corner_chart, kind="stable")
    starts = np.searchsorted(corner_chart[order], np.arange(n_l))
    present = np.bincount(corner_chart, minlength=n_l) > 0
    starts = np.minimum(starts, len(order) - 1)
    lo = np.stack([np.minimum.reduceat(flat[order, k], starts) for k in range(2)], 1)
    hi = np.stack([np.maximum.reduceat(flat[order, k], starts) for k in range(2)], 1)
    size = np.where(present[:, None], hi - lo, 0.0)

    def boxes(scale):
        return (np.ceil(size[:, 0] * scale).astype(np.int64) + 2 * pad + 1,
                np.ceil(size[:, 1] * scale).astype(np.int64) + 2 * pad + 1)

    area = float((size[:, 0] * size[:, 1]).sum())
    low, high = 0.0, np.sqrt(page * page / max(area, 1e-30))
    for _ in range(18):  # bisection on texels per metre
        mid = 0.5 * (low + high)
        if shelf_pack(*boxes(mid), page) is None:
            high = mid
        else:
            low = mid
    scale = low
    x, y = shelf_pack(*boxes(scale), page)
    tex = (flat - lo[corner_chart]) * scale + np.stack([x, y], 1)[corner_chart] + pad + 0.5
    return tex.reshape(-1, 3, 2), scale  # texel units


# ---------------------------------------------------------------- texture
def _hash01(ix, iy, iz, salt):
    h = (ix.astype(np.uint32) * np.uint32(0x8DA6B343)) ^ (iy.astype(np.uint32) * np.uint32(0xD8163841)) \
        ^ (iz.astype(np.uint32) * np.uint32(0xCB1AB31F)) ^ np.uint32(salt)
    h ^= h >> np.uint32(15)
    h *= np.uint32(0x2C1B3C6D)
    h ^= h >> np.uint32(12)
    h *= np.uint32(0x297A2D39)
    h ^= h >> np.uint32(15)
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(1.0 / (1 << 24))


def value_noise(p: np.ndarray, spacing: float, salt: int) -> np.ndarray:
    """Trilinear value noise in [-0.5, 0.5] with lattice spacing `spacing` (metres)."""
    q = p * np.float32(1.0 / spacing)
    i = np.floor(q)
    f = q - i
    f = f * f * (np.float32(3) - np.float32(2) * f)
    i = i.astype(np.int64)
    out = np.zeros(len(p), dtype=np.float32)
    for dx in (0, 1):
        wx = f[:, 0] if dx else 1 - f[:, 0]
        for dy in (0, 1):
            wy = f[:, 1] if dy else 1 - f[:, 1]
            for dz in (0, 1):
                wz = f[:, 2] if dz else 1 - f[:, 2]
                out += wx * wy * wz * _hash01(i[:, 0] + dx, i[:, 1] + dy, i[:, 2] + dz, salt)
    return out - np.float32(0.5)


def surface_colour(p: np.ndarray, texel: float) -> np.ndarray:
    """RGB uint8 of 3D points: smooth rock-like colour plus detail 2-3 texels wide."""
    p = p.astype(np.float32)
    s1 = np.sin(p @ np.float32([4.1, -2.3, 3.3]) + np.float32(0.7))
    s2 = np.sin(p @ np.float32([-1.7, 5.2, 2.9]) + np.float32(2.1))
    s3 = np.sin(p @ np.float32([2.6, 3.4, -6.1]) + np.float32(4.0))
    bands = np.sin(p @ np.float32([31.0, 12.0, -22.0]))  # strata a few centimetres apart
    mid = value_noise(p, 24 * texel, 7)
    fine = value_noise(p, 2.5 * texel, 11)
    lum = np.float32(0.08) * bands + np.float32(0.25) * mid + np.float32(0.30) * fine
    rgb = np.stack([np.float32(0.55) + np.float32(0.18) * s1 + np.float32(0.06) * s2 + lum,
                    np.float32(0.46) + np.float32(0.12) * s1 + np.float32(0.09) * s3 + lum,
                    np.float32(0.36) + np.float32(0.08) * s2 + np.float32(0.10) * s3 + np.float32(0.9) * lum], 1)
    return np.clip(rgb * np.float32(255) + np.float32(0.5), 0, 255).astype(np.uint8)


def bake_texture(tex_uv: np.ndarray, corners3d: np.ndarray, page: int, texel: float,
                 gutter: float = 1.5, budget: int = 3_000_000) -> np.ndarray:
    """Rasterises every triangle (plus a gutter) into a (page, page, 3) image, row 0 at v = 0."""
    img = np.zeros((page * page, 3), dtype=np.uint8)
    filled = np.zeros(page * page, dtype=bool)
    t = tex_uv.astype(np.float64)
    lo = np.floor(t.min(axis=1) - gutter - 0.5).astype(np.int64) + 1  # first texel whose centre may count
    hi = np.floor(t.max(axis=1) + gutter - 0.5).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, page - 1)
    ext = np.maximum(hi - lo + 1, 0)
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    ok = np.abs(area2) > 1e-9
    kmax = ext.max(axis=1)
    order = np.argsort(kmax, kind="stable")
    order = order[ok[order] & (kmax[order] > 0)]
    start = 0
    while start < len(order):
        k = int(kmax[order[start]])
        n = max(1, budget // (k * k))
        k = int(kmax[order[min(len(order), start + n) - 1]])
        n = max(1, min(n, budget // (k * k)))
        idx = order[start:start + n]
        k = int(kmax[idx].max())
        start += len(idx)
        oy, ox = np.divmod(np.arange(k * k), k)
        valid = (ox[None, :] < ext[idx, 0:1]) & (oy[None, :] < ext[idx, 1:2])
        tri_of = np.broadcast_to(np.arange(len(idx))[:, None], valid.shape)[valid]
        px = (lo[idx, 0][:, None] + ox[None, :])[valid]
        py = (lo[idx, 1][:, None] + oy[None, :])[valid]
        cxp, cyp = px + 0.5, py + 0.5
        ta = a[idx][tri_of]
        tb = b[idx][tri_of]
        tc = c[idx][tri_of]
        sgn = np.sign(area2[idx])[tri_of]

        def edge(p0, p1):
            ex, ey = p1[:, 0] - p0[:, 0], p1[:, 1] - p0[:, 1]
            e = ex * (cyp - p0[:, 1]) - ey * (cxp - p0[:, 0])
            return e, np.sqrt(ex * ex + ey * ey)

        e_bc, l_bc = edge(tb, tc)
        e_ca, l_ca = edge(tc, ta)
        e_ab, l_ab = edge(ta, tb)
        dist = np.minimum(np.minimum(sgn * e_bc / l_bc, sgn * e_ca / l_ca), sgn * e_ab / l_ab)
        keep = dist >= -gutter
        inside = dist[keep] >= 0
        tri_k = tri_of[keep]
        ar = area2[idx][tri_k]
        la, lb, lc = e_bc[keep] / ar, e_ca[keep] / ar, e_ab[keep] / ar
        faces = idx[tri_k]
        p3 = (la[:, None] * corners3d[faces, 0] + lb[:, None] * corners3d[faces, 1]
              + lc[:, None] * corners3d[faces, 2])
        col = surface_colour(p3, texel)
        flat = py[keep] * page + px[keep]
        g = ~inside & ~filled[flat]
        img[flat[g]] = col[g]
        img[flat[inside]] = col[inside]
        filled[flat[inside]] = True
    return img.reshape(page, page, 3)


# ---------------------------------------------------------------- output
def write_obj(folder: Path, name: str, pos, tris, label, tex_uv, page: int) -> None:
    corner_key = np.repeat(label, 3) * len(pos) + tris.reshape(-1)
    uniq, first, inverse = np.unique(corner_key, return_index=True, return_inverse=True)
    vt = tex_uv.reshape(-1, 2)[first] / page
    with open(folder / f"{name}.mtl", "w") as mtl:
        mtl.write(f"newmtl scan\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {name}_color.png\n")
    with open(folder / f"{name}.obj", "w") as obj:
        obj.write(f"# Atlas Defrag benchmark scan (bench/make_large_scan.py v{GENERATOR_VERSION})\n")
        obj.write(f"mtllib {name}.mtl\no {name}\n")
        np.savetxt(obj, pos, fmt="v %.7f %.7f %.7f")
        np.savetxt(obj, vt, fmt="vt %.8f %.8f")
        obj.write("usemtl scan\n")
        rows = np.stack([tris + 1, inverse.reshape(-1, 3) + 1], axis=2).reshape(-1, 6)
        np.savetxt(obj, rows, fmt="f %d/%d %d/%d %d/%d")


def generate(out_dir: Path, grid: int = 290, charts: int = 15000, page: int = 8192, seed: int = 1,
             force: bool = False) -> Path:
    """Writes the scan if needed; returns the OBJ path."""
    default = (grid, charts, page, seed) == (290, 15000, 8192, 1)
    folder = Path(out_dir) / ("large_scan" if default else f"large_scan_g{grid}_c{charts}_p{page}_s{seed}")
    obj_path = folder / "large_scan.obj"
    params = {"version": GENERATOR_VERSION, "grid": grid, "charts": charts, "page": page, "seed": seed}
    meta_path = folder / "meta.json"
    if not force and meta_path.exists() and obj_path.exists() and (folder / "large_scan_color.png").exists():
        meta = json.loads(meta_path.read_text())
        if meta.get("params") == params:
            return obj_path
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    dirs, tris = cube_sphere(grid)
    pos = displace(dirs, rng)
    tris = orient_outward(pos, tris)
    log(f"mesh: {len(pos):,} vertices, {len(tris):,} triangles ({time.perf_counter() - t0:.1f} s)")
    label = grow_charts(len(tris), face_adjacency(tris, len(pos)), charts, rng)
    uv_m, label = flatten_charts(pos, tris, label)
    tex_uv, scale = pack_atlas(uv_m, label, page, pad=2)
    log(f"atlas: {int(label.max()) + 1:,} charts, {scale:.0f} texels/m ({time.perf_counter() - t0:.1f} s)")
    corners3d = pos[tris]
    img = bake_texture(tex_uv, corners3d, page, texel=1.0 / scale)
    log(f"texture baked ({time.perf_counter() - t0:.1f} s)")
    from PIL import Image
    Image.fromarray(img[::-1]).save(folder / "large_scan_color.png", compress_level=1)
    del img
    write_obj(folder, "large_scan", pos, tris, label, tex_uv, page)
    meta = {"params": params, "vertices": int(len(pos)), "triangles": int(len(tris)),
            "charts_grown": int(label.max()) + 1, "texels_per_metre": scale,
            "seconds": round(time.perf_counter() - t0, 1)}
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    log(f"written {obj_path} ({meta['seconds']} s)")
    return obj_path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=HERE / ".cache")
    p.add_argument("--grid", type=int, default=290, help="cells per cube face side (triangles = 12 grid^2)")
    p.add_argument("--charts", type=int, default=15000)
    p.add_argument("--page", type=int, default=8192)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--force", action="store_true", help="regenerate even if the cache matches")
    a = p.parse_args(argv)
    print(generate(a.out, a.grid, a.charts, a.page, a.seed, a.force))
    return 0


if __name__ == "__main__":
    sys.exit(main())
