# SPDX-License-Identifier: MIT
"""The defragmentation job on plain data: no bpy in this module.

The bpy read module turns an object into a :class:`JobInput`; :func:`run` calls
the native core (``_native.defragment``, then ``_native.bake_maps`` once per
material group and set of roles whose images share their sizes; all of it
again at a higher texel density where the colour guard asks for it) and
returns a :class:`JobResult` that the bpy write module turns back into a UV
map, images and material links.

Conventions (shared with ``_native``):
  * UVs are per triangle corner, shape (F, 3, 2), in page units: [0, 1] spans
    the page (values outside wrap).
  * Pixel arrays are (H, W, C), C-contiguous, row 0 = bottom (v = 0), uint8 or
    float32, values in their stored encoding (no colour transform).
  * ``face_page == -1`` marks a face without texture: its UVs pass through.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import options as schema


class DefragError(Exception):
    """A problem the user can act on; the message says what and where."""


class DefragCancelled(DefragError):
    """The run was cancelled; nothing was written."""


# Stages of _native.defragment, each reporting its own fraction 0..1.
LAYOUT_STAGES = ("charts", "aggregate", "flatten", "pack")

# Roles in a fixed order; anything else sorts after these by name.
ROLE_ORDER = ("base_color", "metallic", "roughness", "occlusion", "emission", "alpha", "normal")


def role_sort_key(role: str):
    return (ROLE_ORDER.index(role) if role in ROLE_ORDER else len(ROLE_ORDER), role)


@dataclass
class ImageData:
    """One source image's pixels and the format its output must keep."""

    name: str
    pixels: np.ndarray  # (H, W, C) uint8 or float32, row 0 = bottom
    colorspace: str = "sRGB"
    is_float: bool = False
    alpha_mode: str = "STRAIGHT"

    @property
    def size(self) -> Tuple[int, int]:
        """(width, height)"""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])


@dataclass
class ImageMap:
    """One image feeding one role of a source page."""

    role: str  # 'base_color', 'roughness', 'metallic+roughness', 'normal', ...
    image: str  # key into JobInput.images
    normal_map: bool = False  # tangent-space normal map: re-orient on bake


@dataclass
class SourcePage:
    """A texture space shared by the materials whose image maps are identical."""

    maps: List[ImageMap]
    group: int  # pages of one group have the same roles and formats

    def roles(self) -> Tuple[str, ...]:
        return tuple(m.role for m in self.maps)

    def map_for(self, role: str) -> ImageMap:
        for m in self.maps:
            if m.role == role:
                return m
        raise KeyError(role)


@dataclass
class MeshData:
    positions: np.ndarray  # (V, 3) float64
    triangles: np.ndarray  # (F, 3) int32
    uvs: np.ndarray  # (F, 3, 2) float64, page units
    face_page: np.ndarray  # (F,) int32, -1 = untextured
    # (F,) int32: the polygon each triangle comes from, whose triangles change
    # charts together (a polygon corner holds one UV); None: triangles only.
    polygons: Optional[np.ndarray] = None


@dataclass
class JobInput:
    mesh: MeshData
    pages: List[SourcePage]
    images: Dict[str, ImageData]


class Options:
    """The user options of options.SCHEMA as attributes, defaults from there."""

    def __init__(self, **values):
        unknown = sorted(set(values) - set(schema.BY_NAME))
        if unknown:
            raise TypeError("unknown option(s): " + ", ".join(unknown))
        for o in schema.SCHEMA:
            setattr(self, o.name, values.get(o.name, o.default))

    def validate(self) -> None:
        try:
            self.__dict__.update(schema.validate(self.values()))
        except ValueError as exc:
            raise DefragError(str(exc)) from exc

    def values(self) -> dict:
        """Every option by name."""
        return {o.name: getattr(self, o.name) for o in schema.SCHEMA}

    def native(self) -> dict:
        """The keyword options of _native.defragment (the same names)."""
        return {o.name: getattr(self, o.name) for o in schema.SCHEMA if not (o.bake or o.job)}

    def bake(self) -> dict:
        """The keyword options of _native.bake_maps (the same names)."""
        return {o.name: getattr(self, o.name) for o in schema.SCHEMA if o.bake}


@dataclass
class OutputImage:
    page: int  # new page index
    role: str
    source: str  # key of the source image it continues (name, format)
    pixels: np.ndarray  # (H, W, C), same dtype as the source
    colorspace: str = "sRGB"
    is_float: bool = False
    alpha_mode: str = "STRAIGHT"


@dataclass
class JobResult:
    uvs: np.ndarray  # (F, 3, 2) float64, page units of the new pages
    face_page: np.ndarray  # (F,) int32, -1 kept for untextured faces
    page_sizes: np.ndarray  # (Q, 2) int32 [width, height]
    page_group: np.ndarray  # (Q,) int32 group of each new page
    images: List[OutputImage] = field(default_factory=list)
    report: dict = field(default_factory=dict)

    def image_for(self, page: int, role: str) -> OutputImage:
        for im in self.images:
            if im.page == page and im.role == role:
                return im
        raise KeyError((page, role))


Progress = Optional[Callable[[str, float], None]]


def page_sizes_of(job: JobInput) -> np.ndarray:
    """Reference size of each source page: its largest image (by area)."""
    sizes = np.zeros((len(job.pages), 2), dtype=np.int32)
    for p, page in enumerate(job.pages):
        best = (0, 0)
        for m in page.maps:
            w, h = job.images[m.image].size
            if w * h > best[0] * best[1]:
                best = (w, h)
        sizes[p] = best
    return sizes


# How far (in UV units) a face may reach past the page before a texture that
# does not repeat the image shows something else there: round-off only.
_EDGE_SLACK = 1e-4


def reaches_past_page(uvs: np.ndarray) -> bool:
    """Whether any of these UVs lies outside [0, 1], beyond round-off: where a
    texture set to clamp or mirror differs from the bake, which repeats."""
    return bool(uvs.size) and bool(uvs.min() < -_EDGE_SLACK or uvs.max() > 1 + _EDGE_SLACK)


def with_channels(pixels: np.ndarray, channels: int) -> np.ndarray:
    """C-contiguous (H, W, channels) of (H, W, C <= channels) pixels, the
    missing channels filled as Blender fills them: a grey image's grey in R,
    G and B, else 0, and alpha 1 (255). The bake's input and the add-on's
    RGBA images both take this."""
    if pixels.shape[2] == channels:
        return np.ascontiguousarray(pixels)
    h, w, c = pixels.shape
    out = np.zeros((h, w, channels), dtype=pixels.dtype)
    if c == 1:
        out[..., : min(3, channels)] = pixels
    else:
        out[..., : min(c, channels)] = pixels[..., : min(c, channels)]
    if channels == 4 and c < 4:
        out[..., 3] = 1.0 if pixels.dtype != np.uint8 else 255
    return out


def _opaque(pixels: np.ndarray) -> bool:
    """Whether an (H, W, 4) image's alpha is 1 (255) everywhere."""
    return bool(pixels[..., 3].min() == (255 if pixels.dtype == np.uint8 else 1.0))  # min: no temporary array


def _bake_channels(sources, normal_map: bool) -> int:
    """The channels a role bakes: the most its images have, without an
    alpha that is opaque in all of them (most scans' RGBA PNGs), which
    would add a quarter to the bake, the write and every later read for
    nothing; a grey normal map bakes X, Y and Z (the bake turns X and Y)."""
    channels = max(s.pixels.shape[2] for s in sources)
    if channels == 4 and all(_opaque(s.pixels) for s in sources if s.pixels.shape[2] == 4):
        channels = 3
    return 3 if normal_map and channels == 1 else channels


def check_input(job: JobInput) -> None:
    """Shapes and references; raises DefragError naming the problem."""
    m = job.mesh
    f = len(m.triangles)
    if m.positions.ndim != 2 or m.positions.shape[1] != 3:
        raise DefragError(f"positions must be (V, 3), got {m.positions.shape}")
    if m.triangles.shape != (f, 3) or m.uvs.shape != (f, 3, 2) or m.face_page.shape != (f,):
        raise DefragError("triangles, uvs and face_page disagree on the face count")
    if f == 0:
        raise DefragError("the mesh has no faces")
    if not len(job.pages) or not np.any(m.face_page >= 0):
        raise DefragError("no face uses an image texture")
    if m.face_page.max() >= len(job.pages):
        raise DefragError("face_page refers to a page that does not exist")
    for p, page in enumerate(job.pages):
        if not page.maps:
            raise DefragError(f"page {p} has no image")
        for im in page.maps:
            if im.image not in job.images:
                raise DefragError(f"page {p} refers to unknown image {im.image!r}")


class _NativeCalls:
    """Calls into the native module: its errors as DefragError or
    DefragCancelled, its progress mapped onto a share of the caller's bar."""

    def __init__(self, native, progress: Progress, cancel):
        self.native = native
        self.progress = progress
        self.cancel = cancel

    def __call__(self, fn, *args, **kwargs):
        try:
            return fn(*args, cancel=self.cancel, **kwargs)
        except self.native.Cancelled as exc:
            raise DefragCancelled("cancelled") from exc
        except ValueError as exc:
            raise DefragError(str(exc)) from exc

    def named(self, prefix: str) -> "_NativeCalls":
        """The same calls, their stages reported as prefix + stage."""
        if self.progress is None:
            return self
        progress = self.progress
        return _NativeCalls(self.native, lambda stage, fraction: progress(prefix + stage, fraction), self.cancel)

    def share(self, offset: float, share: float, stages: Sequence[str] = ()):
        """Maps a call's (stage, fraction) onto [offset, offset + share]; a
        call with several stages reports each from 0 to 1, in this order."""
        if self.progress is None:
            return None
        progress = self.progress
        last = [0.0]

        def report(stage: str, fraction: float) -> None:
            f = max(0.0, min(1.0, float(fraction)))
            if stage in stages:
                f = (stages.index(stage) + f) / len(stages)
            elif stages:
                f = last[0]
            last[0] = max(last[0], f)
            progress(stage, offset + share * last[0])
        return report


@dataclass
class _Layout:
    """The new layout, and what run() knows about the job around it."""

    job: JobInput
    face_group: np.ndarray  # (F,) int32 material group; untextured faces have their own
    src_sizes: np.ndarray  # (P, 2) int32 reference size of each source page
    uvs: np.ndarray  # (F, 3, 2) float64, the new UVs
    face_page: np.ndarray  # (F,) int32 new page
    page_sizes: np.ndarray  # (Q, 2) int32
    page_padding: np.ndarray  # (Q,) int32 texels of padding the packer kept on each page
    report: dict


def run(job: JobInput, options: Options, progress: Progress = None, cancel=None,
        native=None) -> JobResult:
    """Defragments the atlas and bakes every image map to the new layout.

    ``native`` is the ``_native`` module (imported from this package when None).
    Raises DefragError (bad input, with the core's message), DefragCancelled,
    or MemoryError. Never touches anything outside the returned result.
    """
    if native is None:
        from . import _native as native  # noqa: PLW0621
    options.validate()
    check_input(job)
    calls = _NativeCalls(native, progress, cancel)
    t_start = time.perf_counter()
    bake_calls = _bake_batches(job)
    first = _attempt(job, options, calls, bake_calls, 0.0, _FIRST_SHARE if _guard_may_run(options) else 1.0)
    kept, guard = _keep_detail(job, options, calls, bake_calls, first)
    layout, images, texels = kept.layout, kept.images, kept.texels
    page_group = _new_page_groups(layout)
    t_end = time.perf_counter()

    report = layout.report
    seconds = dict(report.get("seconds", {}) or {})
    seconds.setdefault("layout", kept.layout_seconds)
    seconds["bake"] = kept.bake_seconds
    # The guard's checks and the attempts it did not keep (the first, when a re-run is kept).
    seconds["detail"] = t_end - t_start - kept.layout_seconds - kept.bake_seconds
    seconds["total"] = t_end - t_start
    report.update(guard)
    report.update(seconds=seconds, pages_before=int(len(job.pages)),
                  pages_after=int(len(layout.page_sizes)), images_written=len(images),
                  padding=int(layout.page_padding.min(initial=options.padding)),
                  copied_share=texels["copied_texels"] / max(1, texels["covered_texels"]))
    report["warnings"] = _size_warnings(report, options, _chart_texels(layout)) + _winding_warnings(report)
    if progress is not None:
        progress("done", 1.0)
    return JobResult(uvs=layout.uvs, face_page=layout.face_page, page_sizes=layout.page_sizes,
                     page_group=page_group, images=images, report=report)


@dataclass
class _Attempt:
    """A layout and the images baked onto it."""

    layout: _Layout
    images: List[OutputImage]
    texels: dict  # covered_texels, copied_texels
    layout_seconds: float
    bake_seconds: float


def _attempt(job: JobInput, options: Options, calls: _NativeCalls, bake_calls, offset: float,
             share: float) -> _Attempt:
    """The layout, then every bake call, reported on [offset, offset + share]
    of the progress bar: layout first, then every bake call alike."""
    t0 = time.perf_counter()
    layout_share = share * (0.5 if bake_calls else 1.0)
    bake_share = (share - layout_share) / max(1, len(bake_calls))
    layout = _new_layout(job, options, calls, calls.share(offset, layout_share, LAYOUT_STAGES))
    t1 = time.perf_counter()
    images: List[OutputImage] = []
    texels = {"covered_texels": 0, "copied_texels": 0}
    for i, (g, roles) in enumerate(bake_calls):
        baked, stats = _bake_group_roles(layout, g, roles, options, calls,
                                         calls.share(offset + layout_share + i * bake_share, bake_share))
        images.extend(baked)
        for key in texels:
            texels[key] += stats[key]
    return _Attempt(layout, images, texels, t1 - t0, time.perf_counter() - t1)


# Texel densities (times the one asked for) the colour guard tries in turn,
# and the least PSNR (dB) a step must add to be worth its texels.
_DETAIL_STEPS = (1.25, 1.5, 2.0)
_DETAIL_GAIN = 0.5
# dB of PSNR a doubling of the texel density buys on sharp textures, on the
# low side (bench/README.md, "A colour guard for textures that carry full
# detail"): the guard starts at the step this says the shortfall needs,
# since each step costs a whole layout and bake.
_DETAIL_DB_PER_DOUBLING = 5.0
# The progress bar's share of the first layout and bake; the colour guard's
# steps share the rest, so that the bar never goes back.
_FIRST_SHARE = 0.8


def _keep_detail(job: JobInput, options: Options, calls: _NativeCalls, bake_calls, first: _Attempt):
    """The colour guard (min_colour_psnr): while the new base colour's PSNR
    stays under it, the job again at the next of _DETAIL_STEPS (from the
    one the shortfall calls for), as long as the pages stay as many and
    within the source's texels at the density asked for, and each step adds
    _DETAIL_GAIN. Resampling at the source's density blurs texels that carry
    full detail; more texels keep it. A density the user set (below the
    source's, a fixed page size, texels per unit) is left as it is. Returns
    the attempt kept and the report's colour_psnr (None: not measured) and
    detail_scale."""
    report = first.layout.report
    if not _guard_may_run(options) or report.get("shrunk"):
        return first, {"colour_psnr": None, "detail_scale": 1.0}
    psnr = _colour_psnr(job, first, calls.native)
    seen = {"colour_psnr": psnr, "detail_scale": 1.0}
    if psnr is None or psnr >= options.min_colour_psnr:
        return first, seen
    steps = _detail_steps(options, psnr, report)
    kept = first
    share = (1.0 - _FIRST_SHARE) / max(1, len(steps))
    for k, step in enumerate(steps):
        raised = Options(**dict(options.values(), density_scale=options.density_scale * step))
        attempt = _attempt(job, raised, calls.named(f"colour guard {step:g}x: "), bake_calls,
                           _FIRST_SHARE + k * share, share)
        new_psnr = _colour_psnr(job, attempt, calls.native)
        if _outgrew(attempt, first, options) or new_psnr is None or new_psnr < psnr + _DETAIL_GAIN:
            break
        kept, psnr, seen = attempt, new_psnr, {"colour_psnr": new_psnr, "detail_scale": step}
        if psnr >= options.min_colour_psnr:
            break
    return kept, seen


def _guard_may_run(options: Options) -> bool:
    """Whether the colour guard is on and the density is not the user's own
    (a density scale below 1, a fixed page size, texels per unit)."""
    chosen = options.density_scale < 1 or options.fixed_page_size or options.texels_per_unit
    return options.min_colour_psnr > 0 and not chosen


def _source_texels(report: dict, options: Options) -> float:
    """The source's texels at the density asked for."""
    return report.get("texels_before", 0) * options.density_scale ** 2


def _detail_steps(options: Options, psnr: float, report: dict) -> List[float]:
    """The densities the guard tries, from the one the shortfall calls for:
    those whose pages would stay within the source's texels."""
    budget = _source_texels(report, options)
    highest = schema.BY_NAME["density_scale"].high
    steps = [step for step in _DETAIL_STEPS
             if report.get("texels_after", 0) * step ** 2 <= budget and options.density_scale * step <= highest]
    needed = 2.0 ** ((options.min_colour_psnr - psnr) / _DETAIL_DB_PER_DOUBLING)
    start = next((k for k, step in enumerate(steps) if step >= needed), len(steps) - 1)
    return steps[start:]


def _outgrew(attempt: _Attempt, first: _Attempt, options: Options) -> bool:
    """Whether a step of the guard shrank its charts, took more pages than the
    first attempt or more texels than the source holds at the density asked for."""
    report = attempt.layout.report
    return (bool(report.get("shrunk")) or len(attempt.layout.page_sizes) > len(first.layout.page_sizes)
            or report.get("texels_after", 0) > _source_texels(first.layout.report, options))


def _colour_psnr(job: JobInput, attempt: _Attempt, native) -> Optional[float]:
    """PSNR of the new base colour against the old (compare_colors, 400,000
    points over the surface), on the faces of pages with a base colour in 8
    bits; None where there are none (float colours have no fixed peak for a
    PSNR bound to mean the same)."""
    def eight_bit(pixels):
        return pixels if pixels is not None and pixels.dtype == np.uint8 else None

    layout, mesh = attempt.layout, job.mesh
    old = [eight_bit(job.images[page.map_for("base_color").image].pixels) if "base_color" in page.roles() else None
           for page in job.pages]
    by_page = {im.page: im.pixels for im in attempt.images if im.role == "base_color"}
    new = [eight_bit(by_page.get(q)) for q in range(len(layout.page_sizes))]
    measured = np.array([a is not None for a in old] + [False])[mesh.face_page]
    measured &= np.array([a is not None for a in new] + [False])[layout.face_page]
    if not measured.any():
        return None
    blank = np.zeros((1, 1, 3), np.uint8)  # the image of a page no measured face is on
    try:
        fidelity = native.compare_colors(
            np.ascontiguousarray(mesh.positions, dtype=np.float64),
            np.ascontiguousarray(mesh.triangles, dtype=np.int32), np.ascontiguousarray(mesh.uvs, dtype=np.float64),
            np.where(measured, mesh.face_page, -1).astype(np.int32), [blank if a is None else a for a in old],
            layout.uvs, np.where(measured, layout.face_page, -1).astype(np.int32),
            [blank if a is None else a for a in new], borders=False)
    except ValueError:  # an input the layout took and the measure does not: no guard
        return None
    return float(fidelity["psnr_db"]) if fidelity["samples"] else None


# New pages past this many times the input's texels (at the density asked
# for) are worth a word: every face gets texels of its own.
_GROWTH_TOLD = 2.0


def _size_warnings(report: dict, options: Options, chart_texels: float) -> List[str]:
    """What the size of the new pages calls for saying: charts shrunk, or
    pages far larger than the input's because its faces shared texels: then
    the charts alone cover more texels than the input's pages hold at the
    density asked for (padding alone can outgrow tiny pages)."""
    if report.get("shrunk"):
        return [f"charts scaled to {report.get('scale', 0):.3g}x the input's texel density, below the density "
                "asked for, to fit max_page_size, max_pages, fixed_page_size or the input's texel count"]
    before, after = report.get("texels_before", 0), report.get("texels_after", 0)
    expected = _source_texels(report, options)
    if options.texels_per_unit or not before or after <= _GROWTH_TOLD * expected or chart_texels <= expected:
        return []
    return [f"the new pages hold {after / expected:.1f}x the input's texels at the density asked for: its faces "
            "share or repeat texels (UVs that overlap or run outside the page), and each face now gets texels "
            "of its own; texels_at_most_input keeps the input's count, at a lower density"]


def _winding_warnings(report: dict) -> List[str]:
    """Faces wound against their neighbours keep the charts apart: said, with
    the fix, as the layout cannot mend the input's winding."""
    edges = report.get("opposed_winding_edges", 0)
    if not edges:
        return []
    return [f"{edges} edges join faces wound opposite ways (normals flipped against their neighbours): no chart "
            "grows across them, so charts and seams stay many; recalculate the normals first (Edit Mode: "
            "Mesh > Normals > Recalculate Outside) and run again"]


def _chart_texels(layout: _Layout) -> float:
    """Texels the new triangles cover: their area on their pages."""
    on_page = layout.face_page >= 0
    uv = layout.uvs[on_page] * layout.page_sizes[layout.face_page[on_page]][:, None, :]
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    return 0.5 * float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())


def _group_count(job: JobInput) -> int:
    return 1 + max(p.group for p in job.pages)


def _group_roles(job: JobInput, group: int) -> Tuple[str, ...]:
    for page in job.pages:
        if page.group == group:
            return page.roles()
    return ()


def _bake_batches(job: JobInput) -> List[Tuple[int, Tuple[str, ...]]]:
    """(group, roles) per bake call: the roles of a group whose images have the
    same sizes, page for page, bake in one pass over the new texels."""
    batches = []
    for g in range(_group_count(job)):
        pages = [p for p in job.pages if p.group == g]
        by_sizes: Dict[tuple, List[str]] = {}
        for role in _group_roles(job, g):
            key = tuple(job.images[p.map_for(role).image].size for p in pages)
            by_sizes.setdefault(key, []).append(role)
        batches.extend((g, tuple(roles)) for roles in by_sizes.values())
    return batches


def _new_layout(job: JobInput, options: Options, calls: _NativeCalls, progress) -> _Layout:
    """_native.defragment on the job, faces kept apart by material group."""
    mesh = job.mesh
    page_group = np.array([p.group for p in job.pages], dtype=np.int32)
    face_group = np.full(len(mesh.triangles), _group_count(job), dtype=np.int32)
    textured = mesh.face_page >= 0
    face_group[textured] = page_group[mesh.face_page[textured]]
    src_sizes = page_sizes_of(job)
    res = calls(
        calls.native.defragment,
        np.ascontiguousarray(mesh.positions, dtype=np.float64),
        np.ascontiguousarray(mesh.triangles, dtype=np.int32),
        np.ascontiguousarray(mesh.uvs, dtype=np.float64),
        np.ascontiguousarray(mesh.face_page, dtype=np.int32),
        src_sizes,
        face_group=face_group,
        face_polygon=None if mesh.polygons is None else np.ascontiguousarray(mesh.polygons, dtype=np.int32),
        options=options.native(),
        progress=progress,
    )
    return _Layout(job=job, face_group=face_group, src_sizes=src_sizes,
                   uvs=np.asarray(res["uvs"], dtype=np.float64),
                   face_page=np.asarray(res["face_page"], dtype=np.int32),
                   page_sizes=np.asarray(res["page_sizes"], dtype=np.int32).reshape(-1, 2),
                   page_padding=np.asarray(res["page_padding"], dtype=np.int32),
                   report=dict(res.get("report", {})))


def _new_page_groups(layout: _Layout) -> np.ndarray:
    """(Q,) group of every new page; raises if the core mixed groups on a page."""
    new_group = np.full(len(layout.page_sizes), -1, dtype=np.int32)
    tex_new = layout.face_page >= 0
    new_group[layout.face_page[tex_new]] = layout.face_group[tex_new]
    bad = tex_new & (new_group[np.maximum(layout.face_page, 0)] != layout.face_group)
    if np.any(bad) or np.any(tex_new != (layout.job.mesh.face_page >= 0)):
        raise DefragError("internal error: the new layout mixes material groups or texture state")
    return new_group


def _bake_group_roles(layout: _Layout, group: int, roles: Sequence[str], options: Options, calls: _NativeCalls,
                      progress) -> Tuple[List[OutputImage], dict]:
    """_native.bake_maps of some roles of one material group onto its new pages
    (one call per pixel dtype), and what it copied texel for texel
    (covered_texels, copied_texels, summed over the roles)."""
    job, mesh = layout.job, layout.job.mesh
    faces = np.nonzero(layout.face_group == group)[0]
    stats = {"covered_texels": 0, "copied_texels": 0}
    if not len(faces):
        return [], stats
    old_pages = np.unique(mesh.face_page[faces])
    new_pages = np.unique(layout.face_page[faces])
    by_dtype: Dict[type, List[tuple]] = {}
    for role in roles:
        maps = [job.pages[p].map_for(role) for p in old_pages]
        sources = [job.images[m.image] for m in maps]
        channels = _bake_channels(sources, any(m.normal_map for m in maps))
        dtype = np.float32 if any(s.pixels.dtype != np.uint8 for s in sources) else np.uint8
        pixels = [with_channels(s.pixels.astype(dtype, copy=False), channels) for s in sources]
        by_dtype.setdefault(dtype, []).append((role, maps, sources, pixels))
    images: List[OutputImage] = []
    for batch in by_dtype.values():
        baked, counted = calls(
            calls.native.bake_maps,
            np.ascontiguousarray(mesh.uvs[faces], dtype=np.float64),
            _local_index(old_pages, len(job.pages))[mesh.face_page[faces]],
            [pixels for _, _, _, pixels in batch],
            np.ascontiguousarray(layout.uvs[faces], dtype=np.float64),
            _local_index(new_pages, len(layout.page_sizes))[layout.face_page[faces]],
            _output_sizes(layout, old_pages, new_pages, batch[0][2]),
            normal_maps=[any(m.normal_map for m in maps) for _, maps, _, _ in batch],
            padding=int(layout.page_padding[new_pages].max()),
            progress=progress,
            with_stats=True,
            **options.bake(),
        )
        for key in stats:
            stats[key] += counted[key]
        # The first source of the role names the output and gives its format.
        for (role, maps, sources, _), pages in zip(batch, baked):
            first = sources[0]
            images.extend(OutputImage(page=int(new_pages[q_local]), role=role, source=maps[0].image,
                                      pixels=np.asarray(arr), colorspace=first.colorspace,
                                      is_float=first.is_float, alpha_mode=first.alpha_mode)
                          for q_local, arr in enumerate(pages))
    return images, stats


def _local_index(pages: np.ndarray, count: int) -> np.ndarray:
    """(count,) int32: the position of each page in pages, -1 if absent."""
    local = np.full(count, -1, dtype=np.int32)
    local[pages] = np.arange(len(pages), dtype=np.int32)
    return local


def _output_sizes(layout: _Layout, old_pages, new_pages, sources) -> np.ndarray:
    """(len(new_pages), 2) int32: the new pages scaled like the largest source
    of this role relative to its page's reference size."""
    ratio = np.ones(2)
    for k, (p, s) in enumerate(zip(old_pages, sources)):
        r = np.array(s.size, dtype=np.float64) / np.maximum(layout.src_sizes[p], 1)
        ratio = r if k == 0 else np.maximum(ratio, r)
    return np.maximum(1, np.rint(layout.page_sizes[new_pages] * ratio[None, :])).astype(np.int32)


def concatenate(jobs: Sequence[JobInput]) -> Tuple[JobInput, List[slice]]:
    """One job over several objects' jobs, for one atlas shared by all, and
    each job's faces in it. Pages with the same image maps become one page;
    pages whose roles and formats agree share a group, so their charts are
    packed onto the same new pages. Every mesh is moved clear of the ones
    before it along x: the core welds equal positions, and two objects must
    share no vertex. The translation changes no shape, area or normal."""
    page_index: Dict[tuple, int] = {}
    group_index: Dict[tuple, int] = {}
    pages: List[SourcePage] = []
    images: Dict[str, ImageData] = {}
    positions, triangles, uvs, face_page, polygons, faces = [], [], [], [], [], []
    n_verts = n_faces = n_polygons = 0
    x_end = 0.0
    for job in jobs:
        images.update(job.images)
        local = np.empty(len(job.pages), dtype=np.int32)
        for p, page in enumerate(job.pages):
            key = tuple((m.role, m.image, m.normal_map) for m in page.maps)
            if key not in page_index:
                gkey = tuple((m.role, images[m.image].colorspace, images[m.image].is_float) for m in page.maps)
                page_index[key] = len(pages)
                pages.append(SourcePage(maps=list(page.maps), group=group_index.setdefault(gkey, len(group_index))))
            local[p] = page_index[key]
        m = job.mesh
        shift = x_end - m.positions[:, 0].min() + 1.0 if n_verts else 0.0
        positions.append(m.positions + np.array([shift, 0.0, 0.0]))
        x_end = positions[-1][:, 0].max()
        triangles.append(m.triangles + n_verts)
        uvs.append(m.uvs)
        face_page.append(np.where(m.face_page >= 0, local[np.maximum(m.face_page, 0)], -1).astype(np.int32))
        own = np.arange(len(m.triangles), dtype=np.int64) if m.polygons is None else m.polygons.astype(np.int64)
        polygons.append(own + n_polygons)  # each job's polygons apart from the others'
        n_polygons += int(own.max()) + 1 if len(own) else 0
        faces.append(slice(n_faces, n_faces + len(m.triangles)))
        n_verts += len(m.positions)
        n_faces += len(m.triangles)
    shared = any(job.mesh.polygons is not None for job in jobs)
    mesh = MeshData(positions=np.concatenate(positions), triangles=np.concatenate(triangles).astype(np.int32),
                    uvs=np.concatenate(uvs), face_page=np.concatenate(face_page),
                    polygons=np.concatenate(polygons).astype(np.int32) if shared else None)
    return JobInput(mesh=mesh, pages=pages, images=images), faces


def split(result: JobResult, faces: slice) -> JobResult:
    """The part of a shared atlas's result on one job's faces (see
    concatenate): its UVs and pages, the new pages and images of all."""
    return JobResult(uvs=result.uvs[faces], face_page=result.face_page[faces], page_sizes=result.page_sizes,
                     page_group=result.page_group, images=result.images, report=dict(result.report))


def loop_uvs(tri_loops: np.ndarray, uvs: np.ndarray, n_loops: int,
             fallback: Optional[Callable[[], np.ndarray]] = None) -> Tuple[np.ndarray, int]:
    """Per-loop UVs (L, 2) from per-corner UVs; also the number of loops whose
    triangles disagree (a polygon split between charts keeps one of them).
    fallback gives the (L * 2,) UVs of loops no triangle names; it is called
    only when there are such loops (without it they get 0)."""
    flat_loops = tri_loops.reshape(-1)
    flat_uv = uvs.reshape(-1, 2)
    named = np.bincount(flat_loops, minlength=n_loops)
    out = np.empty((n_loops, 2), dtype=np.float64)
    if not named.all():
        out[:] = 0.0 if fallback is None else np.asarray(fallback(), dtype=np.float64).reshape(n_loops, 2)
    out[flat_loops] = flat_uv  # last write wins for shared loops
    if named.max(initial=0) <= 1:  # triangles only: no loop is shared
        return out, 0
    conflicts = np.abs(out[flat_loops] - flat_uv).max(axis=1) > 1e-6
    return out, int(len(np.unique(flat_loops[conflicts])))


def summary(report: dict) -> str:
    """One line for the Info log."""
    def num(key, fmt="{:.0f}"):
        v = report.get(key)
        return "?" if v is None else fmt.format(v)
    secs = report.get("seconds", {}).get("total")
    detail = detail_text(report)
    return (f"charts {num('charts_before')} -> {num('charts_after')}, "
            f"seam {num('seam_before', '{:.4g}')} -> {num('seam_after', '{:.4g}')}, "
            f"pages {num('pages_before')} -> {num('pages_after')} ({num('padding')} texels of padding), "
            + (f"{num('packing_cuts')} cuts for packing to stay within the source's texels, "
               if report.get("cut_to_fit") else "")
            + (f"charts scaled to {num('scale', '{:.3g}')} of their texel density, " if report.get("shrunk") else "")
            + (f"{detail}, " if detail else "")
            + f"time {'?' if secs is None else f'{secs:.1f}'} s")


def detail_text(report: dict) -> str:
    """What the colour guard did, for the lines that report a run: empty
    unless it raised the texel density."""
    if report.get("detail_scale", 1.0) <= 1.0:
        return ""
    return (f"texel density raised {report['detail_scale']:.3g}x to keep the colour's detail "
            f"(PSNR {report['colour_psnr']:.1f} dB)")
