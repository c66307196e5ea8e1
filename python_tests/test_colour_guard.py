"""The colour guard (option min_colour_psnr): where resampling at the
source's texel density blurs a texture whose texels carry full detail, the
job runs again with more texels, never more than the source holds."""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from atlas_defrag import job


def _job_input(scans, halve: bool) -> job.JobInput:
    """The tetra scan as the job takes it; halve: its texture box-filtered to
    half its side, so that every texel carries detail."""
    import defrag_scan

    inp = defrag_scan.job_input(scans("tetra"))
    if halve:
        for name, image in list(inp.images.items()):
            h, w, c = image.pixels.shape
            pixels = image.pixels[: h // 2 * 2, : w // 2 * 2].reshape(h // 2, 2, w // 2, 2, c).mean(axis=(1, 3))
            inp.images[name] = dataclasses.replace(image, pixels=np.rint(pixels).astype(image.pixels.dtype))
    return inp


def _psnr(native, inp: job.JobInput, result: job.JobResult) -> float:
    """The base colour's PSNR over the surface, measured apart from the job."""
    import defrag_scan

    old, new = defrag_scan.colours(inp, result)
    mesh = inp.mesh
    return native.compare_colors(mesh.positions, mesh.triangles, mesh.uvs, mesh.face_page, old, result.uvs,
                                 result.face_page, new)["psnr_db"]


def test_a_sharp_texture_gets_more_texels_within_the_sources(native, scans):
    inp = _job_input(scans, halve=True)
    guarded = job.run(inp, job.Options(), native=native)
    plain = job.run(inp, job.Options(min_colour_psnr=0), native=native)
    report = guarded.report
    assert report["detail_scale"] > 1 and plain.report["detail_scale"] == 1, report["detail_scale"]
    assert plain.report["colour_psnr"] is None
    assert _psnr(native, inp, guarded) > _psnr(native, inp, plain) + 1
    assert abs(report["colour_psnr"] - _psnr(native, inp, guarded)) < 0.5
    assert plain.report["texels_after"] < report["texels_after"] <= report["texels_before"]
    assert "texel density raised" in job.summary(report)


def test_a_texture_resampled_closely_enough_keeps_its_layout(native, scans):
    inp = _job_input(scans, halve=False)
    guarded = job.run(inp, job.Options(), native=native)
    plain = job.run(inp, job.Options(min_colour_psnr=0), native=native)
    assert guarded.report["detail_scale"] == 1 and guarded.report["colour_psnr"] >= 40
    assert np.array_equal(guarded.uvs, plain.uvs)
    assert "texel density raised" not in job.summary(guarded.report)


def _guard_with(monkeypatch, texels_before: int, psnr_at) -> tuple:
    """(densities run, what the guard kept) with the layout and bake faked:
    100 texels at density 1, growing with its square; psnr_at(density)."""
    runs = []

    def attempt(_job, options, *_):
        runs.append(options.density_scale)
        texels = round(100 * options.density_scale ** 2)
        report = {"texels_before": texels_before, "texels_after": texels, "shrunk": False}
        layout = SimpleNamespace(report=report, page_sizes=[(1, 1)])
        return SimpleNamespace(layout=layout, density=options.density_scale)

    monkeypatch.setattr(job, "_attempt", attempt)
    monkeypatch.setattr(job, "_colour_psnr", lambda _job, tried, _native: psnr_at(tried.density))
    first = attempt(None, job.Options())
    kept, seen = job._keep_detail(None, job.Options(), job._NativeCalls(None, None, None), [], first)
    assert seen["detail_scale"] == kept.density
    return runs[1:], kept.density


def test_the_guard_stops_at_the_bound_the_sources_texels_or_a_step_that_adds_little(monkeypatch):
    assert _guard_with(monkeypatch, 1000, lambda d: 34 + 4 * d) == ([1.5], 1.5)  # 40 dB reached
    assert _guard_with(monkeypatch, 1000, lambda d: 38 + 1.5 * (d - 1)) == ([1.5, 2.0], 2.0)
    assert _guard_with(monkeypatch, 200, lambda d: 34 + 4 * d) == ([1.25], 1.25)  # 1.5 would take 225 texels
    assert _guard_with(monkeypatch, 1000, lambda d: 39 + 0.4 * d) == ([1.25], 1.0)  # 0.1 dB: not worth it
    assert _guard_with(monkeypatch, 1000, lambda d: 40.2) == ([], 1.0)
    assert _guard_with(monkeypatch, 120, lambda d: 30 + 4 * d) == ([], 1.0)  # no step fits


def test_the_guard_starts_at_the_step_the_shortfall_calls_for(monkeypatch):
    # 2.5 dB short: at 5 dB a doubling, 1.41x; 5 dB short: 2x at once.
    assert _guard_with(monkeypatch, 1000, lambda d: 32.5 + 5 * d) == ([1.5], 1.5)
    assert _guard_with(monkeypatch, 1000, lambda d: 30 + 5 * d) == ([2.0], 2.0)


def test_a_density_the_user_chose_is_left_as_it_is(native, scans):
    inp = _job_input(scans, halve=True)
    for chosen in ({"density_scale": 0.5}, {"fixed_page_size": 512}, {"texels_per_unit": 300.0}):
        report = job.run(inp, job.Options(**chosen), native=native).report
        assert report["detail_scale"] == 1 and report["colour_psnr"] is None, chosen


def test_the_guard_measures_the_pages_that_have_a_base_colour_and_shows_its_steps(native, scans):
    """A second material group with no base colour (its faces' page holds a
    roughness map only) is left out of the measure, not the guard; the
    guard's steps are named on the progress bar, which never goes back."""
    inp = _job_input(scans, halve=True)
    mesh = inp.mesh
    some = np.arange(len(mesh.triangles)) % 5 == 0
    rough = job.ImageData("rough", inp.images[inp.pages[0].map_for("base_color").image].pixels[:, :, :1].copy(),
                          colorspace="Non-Color")
    inp.images["rough"] = rough
    inp.pages.append(job.SourcePage([job.ImageMap("roughness", "rough")], group=1))
    face_page = np.where(some & (mesh.face_page >= 0), len(inp.pages) - 1, mesh.face_page).astype(np.int32)
    inp = dataclasses.replace(inp, mesh=dataclasses.replace(mesh, face_page=face_page))
    stages = []
    result = job.run(inp, job.Options(), native=native, progress=lambda stage, f: stages.append((stage, f)))
    assert result.report["detail_scale"] > 1 and result.report["colour_psnr"] > 39
    fractions = [f for _, f in stages]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    guard = [f for stage, f in stages if stage.startswith("colour guard")]
    assert guard and job._FIRST_SHARE <= guard[0] < 0.9 and guard[-1] >= 0.99


def test_a_run_cancelled_during_a_step_of_the_guard_is_cancelled(native, scans):
    inp = _job_input(scans, halve=True)
    token = native.CancelToken()

    def progress(stage, _fraction):
        if stage.startswith("colour guard"):
            token.cancel()

    with pytest.raises(job.DefragCancelled):
        job.run(inp, job.Options(), native=native, progress=progress, cancel=token)


def test_a_float_base_colour_leaves_the_guard_to_the_8_bit_pages(native, scans):
    """A page whose base colour is float (no fixed peak for a PSNR bound) is
    left out of the measure; the 8-bit pages are still measured."""
    inp = _job_input(scans, halve=True)
    first = job.run(inp, job.Options(min_colour_psnr=0), native=native)
    attempt = SimpleNamespace(layout=SimpleNamespace(uvs=first.uvs, face_page=first.face_page,
                                                     page_sizes=first.page_sizes), images=first.images)
    alone = job._colour_psnr(inp, attempt, native)
    inp.images["hdr"] = job.ImageData("hdr", np.ones((8, 8, 3), np.float32), is_float=True)
    inp.pages.append(job.SourcePage([job.ImageMap("base_color", "hdr")], group=1))
    assert alone is not None
    assert job._colour_psnr(inp, attempt, native) == alone
