# SPDX-License-Identifier: MIT
"""The bpy-free job module on synthetic data, with the native core."""

from __future__ import annotations

import types

import numpy as np
import pytest


def grid_job(job, n=6, cell=16):
    """An n x n quad grid; each quad is its own UV chart (fragmented atlas).
    Left half: material 0 (base colour 64x64 + normal 128x128), right half:
    material 1 (base colour 32x32), last column: untextured."""
    xs, ys = np.meshgrid(np.arange(n + 1, dtype=np.float64), np.arange(n + 1, dtype=np.float64))
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    tris, uvs, page = [], [], []
    for j in range(n):
        for i in range(n):
            a, b, c, d = j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i
            # Each quad gets a scattered cell in [0,1]^2.
            k = (i * 7 + j * 3) % (n * n)
            u0, v0 = (k % n) / n, (k // n) / n
            s = 0.8 / n
            quad_uv = np.array([[u0, v0], [u0 + s, v0], [u0 + s, v0 + s], [u0, v0 + s]])
            p = -1 if i == n - 1 else (0 if i < n // 2 else 1)
            for tri in ((0, 1, 2), (0, 2, 3)):
                tris.append([(a, b, c, d)[t] for t in tri])
                uvs.append(quad_uv[list(tri)])
                page.append(p)
    rng = np.random.default_rng(0)
    images = {
        "A": job.ImageData("A", rng.integers(0, 255, (64, 64, 4), dtype=np.uint8)),
        "N": job.ImageData("N", rng.integers(0, 255, (128, 128, 4), dtype=np.uint8), colorspace="Non-Color"),
        "B": job.ImageData("B", rng.integers(0, 255, (32, 32, 4), dtype=np.uint8)),
    }
    pages = [job.SourcePage([job.ImageMap("base_color", "A"), job.ImageMap("normal", "N", True)], group=0),
             job.SourcePage([job.ImageMap("base_color", "B")], group=1)]
    mesh = job.MeshData(positions, np.array(tris, np.int32), np.array(uvs, np.float64), np.array(page, np.int32))
    return job.JobInput(mesh, pages, images)


@pytest.fixture(scope="module")
def job(pkg, native):
    return pkg.job


def test_run_groups_roles_sizes(job, native):
    inp = grid_job(job)
    assert job.page_sizes_of(inp).tolist() == [[128, 128], [32, 32]]
    stages = []
    res = job.run(inp, job.Options(padding=2), progress=lambda s, f: stages.append((s, f)))
    f = len(inp.mesh.triangles)
    assert res.uvs.shape == (f, 3, 2) and res.face_page.shape == (f,)
    # Untextured faces pass through, textured ones stay textured.
    untextured = inp.mesh.face_page < 0
    assert np.array_equal(res.face_page < 0, untextured)
    assert np.array_equal(res.uvs[untextured], inp.mesh.uvs[untextured])
    # Pages never mix groups.
    for q in range(len(res.page_sizes)):
        faces = res.face_page == q
        assert len(set(np.asarray([inp.pages[p].group for p in inp.mesh.face_page[faces]]))) <= 1
    # One image per (new page, role). Group 0's reference is its largest image
    # (the 128x128 normal map), so its base colour (64x64) comes out at half
    # the new page size.
    roles = {(im.page, im.role) for im in res.images}
    for q, g in enumerate(res.page_group):
        want = {"base_color", "normal"} if g == 0 else {"base_color"}
        assert {r for p, r in roles if p == q} == want
        for im in res.images:
            if im.page != q:
                continue
            h, w = im.pixels.shape[:2]
            pw, ph = res.page_sizes[q]
            if g == 0 and im.role == "base_color":
                assert (w, h) == (round(pw * 0.5), round(ph * 0.5)), (w, h, pw, ph)
            else:
                assert (w, h) == (pw, ph)
            assert im.pixels.dtype == np.uint8 and im.pixels.shape[2] == 4
    assert res.report["charts_after"] < res.report["charts_before"]
    # Progress is monotonic and ends at 1.
    fr = [x for _, x in stages]
    assert fr == sorted(fr) and fr[-1] == 1.0


def test_cancel_and_errors(job, native):
    inp = grid_job(job)
    token = native.CancelToken()
    token.cancel()
    with pytest.raises(job.DefragCancelled):
        job.run(inp, job.Options(), cancel=token)
    bad = grid_job(job)
    bad.mesh.triangles[0, 0] = 10 ** 6
    with pytest.raises(job.DefragError, match="out of range"):
        job.run(bad, job.Options())
    with pytest.raises(job.DefragError, match="weighting"):
        job.run(grid_job(job), job.Options(weighting="x"))


def test_out_of_memory_is_reported(pkg, native):
    """A MemoryError from the core becomes a clear DefragError."""
    def oom(*a, **k):
        raise MemoryError("std::bad_alloc")
    failing = types.SimpleNamespace(defragment=oom, bake=oom, Cancelled=native.Cancelled)
    inp = grid_job(pkg.job)
    read = types.SimpleNamespace(job=inp)
    with pytest.raises(pkg.DefragError, match="Out of memory"):
        pkg.api.compute(read, pkg.api.Settings(), native=failing)


def test_concatenate_two_objects_into_one_atlas(job, native):
    """Two copies of the grid (equal positions, the same images): one job
    with the pages shared and no vertex shared, one layout covering no texel
    twice, and each part on the same new pages."""
    one = grid_job(job)
    joined, faces = job.concatenate([one, grid_job(job)])
    f = len(one.mesh.triangles)
    assert faces == [slice(0, f), slice(f, 2 * f)]
    assert len(joined.pages) == 2 and [p.group for p in joined.pages] == [0, 1]
    assert len(np.unique(joined.mesh.positions, axis=0)) == 2 * len(one.mesh.positions)
    assert np.array_equal(joined.mesh.face_page[faces[1]], one.mesh.face_page)
    res = job.run(joined, job.Options(padding=2))
    parts = [job.split(res, s) for s in faces]
    assert all(p.uvs.shape == (f, 3, 2) and p.images is res.images for p in parts)
    used = [set(p.face_page[p.face_page >= 0].tolist()) for p in parts]
    assert used[0] == used[1], used
    m = native.measure(joined.mesh.positions, joined.mesh.triangles, joined.mesh.uvs, joined.mesh.face_page,
                       job.page_sizes_of(joined), res.uvs, res.face_page, res.page_sizes)["new"]
    assert m["overlap_texels"] == 0 and m["flipped_faces"] == 0, m


def test_opaque_alpha_is_not_baked(job, native):
    """Images whose alpha is 255 everywhere bake as RGB, to the colours the
    same images without alpha give; a real alpha stays (N's), and a grey
    normal map still bakes X, Y and Z."""
    rgb, opaque = grid_job(job), grid_job(job)
    for name in ("A", "B"):
        rgb.images[name].pixels = np.ascontiguousarray(rgb.images[name].pixels[..., :3])
        opaque.images[name].pixels[..., 3] = 255
    baked = [job.run(inp, job.Options(padding=2)).images for inp in (rgb, opaque)]
    assert [im.role for im in baked[0]] == [im.role for im in baked[1]]
    for a, b in zip(*baked):
        assert a.pixels.shape[2] == b.pixels.shape[2] == (4 if a.role == "normal" else 3)
        assert np.array_equal(a.pixels, b.pixels)
    grey = grid_job(job)
    grey.images["N"].pixels = np.ascontiguousarray(grey.images["N"].pixels[..., :1])
    normals = [im for im in job.run(grey, job.Options(padding=2)).images if im.role == "normal"]
    assert normals and all(im.pixels.shape[2] == 3 for im in normals)


def test_bake_channels_of_mixed_images(job):
    """A role's images may differ in channels: the most win, without an alpha
    opaque in all of them; every channel an image lacks is filled."""
    def source(channels, alpha=255, dtype=np.uint8):
        px = np.full((2, 3, channels), 7, dtype)
        if channels == 4:
            px[..., 3] = alpha
        return types.SimpleNamespace(pixels=px)

    assert job._bake_channels([source(1), source(3)], False) == 3
    assert job._bake_channels([source(1), source(4)], False) == 3
    assert job._bake_channels([source(3), source(4, alpha=254)], False) == 4
    assert job._bake_channels([source(4, alpha=1.0, dtype=np.float32)], False) == 3
    assert job._bake_channels([source(4, alpha=0.5, dtype=np.float32)], False) == 4
    assert job._bake_channels([source(1)], True) == 3 and job._bake_channels([source(2)], True) == 2
    for c in (1, 2, 3):
        for channels in range(c + 1, 5):
            px = np.arange(6 * c, dtype=np.uint8).reshape(2, 3, c) + 1
            out = job.with_channels(px, channels)
            assert out.shape == (2, 3, channels) and out.flags.c_contiguous
            if c == 1:
                assert np.array_equal(out[..., :min(3, channels)], px[..., [0] * min(3, channels)])
            else:
                assert np.array_equal(out[..., :c], px) and not out[..., c:min(3, channels)].any()
            if channels == 4:
                assert (out[..., 3] == 255).all()


def shared_texels_job(job, quads=12, side=64):
    """Separate unit quads, every one mapped onto the whole of one small
    page: the input's faces share all its texels, as mirrored or repeated
    parts do."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    positions = np.concatenate([corners + [2.0 * k, 0, 0] for k in range(quads)])
    tris = np.array([[4 * k, 4 * k + 1, 4 * k + 2] for k in range(quads)] +
                    [[4 * k, 4 * k + 2, 4 * k + 3] for k in range(quads)], np.int32)
    quad_uv = np.array([[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98]])
    uvs = np.array([quad_uv[[0, 1, 2]]] * quads + [quad_uv[[0, 2, 3]]] * quads, np.float64)
    pixels = np.random.default_rng(1).integers(0, 255, (side, side, 4), dtype=np.uint8)
    mesh = job.MeshData(positions, tris, uvs, np.zeros(len(tris), np.int32))
    return job.JobInput(mesh, [job.SourcePage([job.ImageMap("base_color", "A")], group=0)], {"A": job.ImageData("A", pixels)})


def test_pages_far_larger_than_the_input_say_why(job, native):
    """Every face gets texels of its own: an input whose faces share texels
    comes out many times larger, and the report says so and what to do."""
    res = job.run(shared_texels_job(job), job.Options())
    assert res.report["texels_after"] > 10 * res.report["texels_before"]
    assert any("texels_at_most_input" in w for w in res.report["warnings"]), res.report["warnings"]
    small = job.run(shared_texels_job(job), job.Options(texels_at_most_input=True))
    assert not any("input's texels" in w for w in small.report["warnings"]), small.report["warnings"]
    assert not job.run(grid_job(job), job.Options()).report["warnings"]
    # At a low density the padding alone outgrows the tiny pages: nothing shared, nothing said.
    low = job.run(grid_job(job), job.Options(density_scale=0.03))
    assert low.report["texels_after"] > 2 * 0.03 ** 2 * low.report["texels_before"], low.report
    assert not low.report["warnings"], low.report["warnings"]


def test_charts_shrunk_say_by_how_much_against_the_input(job, native):
    """Asked for 4x the input's density on a page too small for it, the
    charts get less: the warning gives the density they got, against the input's."""
    res = job.run(grid_job(job), job.Options(density_scale=4, max_pages=1, max_page_size=128))
    scale = res.report["scale"]
    assert res.report["shrunk"] and 1 < scale < 4, res.report
    assert res.report["warnings"] == [
        f"charts scaled to {scale:.3g}x the input's texel density, below the density asked for, to fit "
        "max_page_size, max_pages, fixed_page_size or the input's texel count"], res.report["warnings"]
