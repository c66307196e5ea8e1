# SPDX-License-Identifier: MIT
"""The defragmentation job on plain data: no bpy in this module.

The bpy read module turns an object into a :class:`JobInput`; :func:`run` calls
the native core (``_native.defragment`` once, then ``_native.bake`` once per
material group and image role) and returns a :class:`JobResult` that the bpy
write module turns back into a UV map, images and material links.

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


class DefragError(Exception):
    """A problem the user can act on; the message says what and where."""


class DefragCancelled(DefragError):
    """The run was cancelled; nothing was written."""


# Roles in a fixed order; anything else sorts after these by name.
# Stages of _native.defragment, each reporting its own fraction 0..1.
LAYOUT_STAGES = ("charts", "aggregate", "flatten", "pack")

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


@dataclass
class JobInput:
    mesh: MeshData
    pages: List[SourcePage]
    images: Dict[str, ImageData]


@dataclass
class Options:
    target_charts: int = 0  # 0 = automatic
    weighting: str = "3d"  # 'uv' or '3d'
    padding: int = 4
    output_size: int = 0  # 0 = automatic (full texel density, smallest page)
    max_page_size: int = 8192
    density_scale: float = 1.0
    max_pages: int = 0  # 0 = as many as the input uses (or as hold its texels); charts shrink past it
    page_sides: str = "multiple_of_4"  # 'tight', 'multiple_of_4' or 'power_of_two'
    square_pages: bool = False
    texels_at_most_input: bool = False  # shrink charts rather than exceed the input's texel count
    texels_per_unit: float = 0.0  # > 0: texels per unit of surface length, replaces density_scale

    def validate(self) -> None:
        w = str(self.weighting).lower()
        if w not in ("uv", "3d"):
            raise DefragError(f"weighting must be 'uv' or '3d', not {self.weighting!r}")
        self.weighting = w
        for name, low in (("target_charts", 0), ("padding", 0), ("output_size", 0), ("max_page_size", 16),
                          ("max_pages", 0)):
            value = getattr(self, name)
            if int(value) != value or value < low:
                raise DefragError(f"{name} must be an integer >= {low}, not {value!r}")
            setattr(self, name, int(value))
        if not (self.density_scale > 0):
            raise DefragError(f"density_scale must be positive, not {self.density_scale!r}")
        if self.page_sides not in ("tight", "multiple_of_4", "power_of_two"):
            raise DefragError(f"page_sides must be 'tight', 'multiple_of_4' or 'power_of_two', not {self.page_sides!r}")
        if not (self.texels_per_unit >= 0):
            raise DefragError(f"texels_per_unit must be >= 0 (0: density_scale applies), not {self.texels_per_unit!r}")
        if self.output_size and self.output_size > self.max_page_size:
            raise DefragError(
                f"output_size {self.output_size} is larger than max_page_size {self.max_page_size}")

    def native(self) -> dict:
        return {
            "target_charts": self.target_charts,
            "weighting": self.weighting,
            "padding": self.padding,
            "output_size": self.output_size,
            "max_page_size": self.max_page_size,
            "density_scale": float(self.density_scale),
            "max_pages": self.max_pages,
            "page_sides": self.page_sides,
            "square_pages": bool(self.square_pages),
            "texels_at_most_input": bool(self.texels_at_most_input),
            "texels_per_unit": float(self.texels_per_unit),
        }


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


def _as_bake_pixels(pixels: np.ndarray, channels: int) -> np.ndarray:
    """C-contiguous (H, W, channels); missing channels: grey 0 / alpha 1."""
    if pixels.shape[2] == channels:
        return np.ascontiguousarray(pixels)
    h, w, c = pixels.shape
    one = 1.0 if pixels.dtype != np.uint8 else 255
    out = np.empty((h, w, channels), dtype=pixels.dtype)
    if c == 1:
        out[..., : min(3, channels)] = pixels[..., :1]
    else:
        out[..., : min(c, channels)] = pixels[..., : min(c, channels)]
    if channels == 4 and c < 4:
        out[..., 3] = one
    return out


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
    mesh = job.mesh
    t_start = time.perf_counter()

    n_groups = 1 + max(p.group for p in job.pages)
    page_group = np.array([p.group for p in job.pages], dtype=np.int32)
    face_group = np.full(len(mesh.triangles), n_groups, dtype=np.int32)  # untextured: own group
    textured = mesh.face_page >= 0
    face_group[textured] = page_group[mesh.face_page[textured]]
    src_sizes = page_sizes_of(job)

    # Share of the progress bar: layout first, then every bake call alike.
    bake_calls = [(g, role) for g in range(n_groups)
                  for role in _group_roles(job, g)]
    layout_share = 0.5 if bake_calls else 1.0
    bake_share = (1.0 - layout_share) / max(1, len(bake_calls))

    def sub_progress(offset: float, share: float, stages: Sequence[str] = ()):
        """Maps a call's (stage, fraction) onto [offset, offset + share]; a
        call with several stages reports each from 0 to 1, in this order."""
        if progress is None:
            return None
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

    def call(fn, *args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except native.Cancelled as exc:
            raise DefragCancelled("cancelled") from exc
        except ValueError as exc:
            raise DefragError(str(exc)) from exc

    res = call(
        native.defragment,
        np.ascontiguousarray(mesh.positions, dtype=np.float64),
        np.ascontiguousarray(mesh.triangles, dtype=np.int32),
        np.ascontiguousarray(mesh.uvs, dtype=np.float64),
        np.ascontiguousarray(mesh.face_page, dtype=np.int32),
        src_sizes,
        face_group=face_group,
        options=options.native(),
        progress=sub_progress(0.0, layout_share, LAYOUT_STAGES),
        cancel=cancel,
    )
    new_uvs = np.asarray(res["uvs"], dtype=np.float64)
    new_face_page = np.asarray(res["face_page"], dtype=np.int32)
    new_sizes = np.asarray(res["page_sizes"], dtype=np.int32).reshape(-1, 2)
    report = dict(res.get("report", {}))
    t_layout = time.perf_counter()

    # Group of every new page (the core never mixes groups on a page).
    new_group = np.full(len(new_sizes), -1, dtype=np.int32)
    tex_new = new_face_page >= 0
    new_group[new_face_page[tex_new]] = face_group[tex_new]
    bad = tex_new & (new_group[np.maximum(new_face_page, 0)] != face_group)
    if np.any(bad) or np.any(tex_new != textured):
        raise DefragError("internal error: the new layout mixes material groups or texture state")

    images: List[OutputImage] = []
    for i, (g, role) in enumerate(bake_calls):
        images.extend(_bake_group_role(
            job, g, role, face_group, src_sizes, new_uvs, new_face_page, new_sizes, options,
            sub_progress(layout_share + i * bake_share, bake_share), cancel, call, native))
    t_end = time.perf_counter()

    seconds = dict(report.get("seconds", {}) or {})
    seconds.setdefault("layout", t_layout - t_start)
    seconds["bake"] = t_end - t_layout
    seconds["total"] = t_end - t_start
    report["seconds"] = seconds
    report["pages_before"] = int(len(job.pages))
    report["pages_after"] = int(len(new_sizes))
    report["images_written"] = len(images)
    if report.get("shrunk"):
        report["warnings"] = [f"charts scaled to {report.get('scale', 0):.3g} of the texel density asked for, "
                              "to fit max_page_size / output_size, max_pages or the texel budget"]
    if progress is not None:
        progress("done", 1.0)
    return JobResult(uvs=new_uvs, face_page=new_face_page, page_sizes=new_sizes,
                     page_group=new_group, images=images, report=report)


def _group_roles(job: JobInput, group: int) -> Tuple[str, ...]:
    for page in job.pages:
        if page.group == group:
            return page.roles()
    return ()


def _bake_group_role(job, group, role, face_group, src_sizes, new_uvs, new_face_page, new_sizes,
                     options, progress, cancel, call, native) -> List[OutputImage]:
    mesh = job.mesh
    faces = np.nonzero(face_group == group)[0]
    if not len(faces):
        return []
    old_pages = np.unique(mesh.face_page[faces])
    new_pages = np.unique(new_face_page[faces])
    old_local = np.full(len(job.pages), -1, dtype=np.int32)
    old_local[old_pages] = np.arange(len(old_pages), dtype=np.int32)
    new_local = np.full(len(new_sizes), -1, dtype=np.int32)
    new_local[new_pages] = np.arange(len(new_pages), dtype=np.int32)

    maps = [job.pages[p].map_for(role) for p in old_pages]
    sources = [job.images[m.image] for m in maps]
    normal_map = any(m.normal_map for m in maps)
    channels = max(s.pixels.shape[2] for s in sources)
    dtype = np.float32 if any(s.pixels.dtype != np.uint8 for s in sources) else np.uint8
    pixels = [_as_bake_pixels(s.pixels.astype(dtype, copy=False), channels) for s in sources]

    # Output resolution: the new page scaled like the largest source of this
    # role relative to its page's reference size.
    ratio = np.ones(2)
    ratio_set = False
    for p, s in zip(old_pages, sources):
        r = np.array(s.size, dtype=np.float64) / np.maximum(src_sizes[p], 1)
        ratio = r if not ratio_set else np.maximum(ratio, r)
        ratio_set = True
    out_sizes = np.maximum(1, np.rint(new_sizes[new_pages] * ratio[None, :])).astype(np.int32)

    baked = call(
        native.bake,
        np.ascontiguousarray(mesh.uvs[faces], dtype=np.float64),
        old_local[mesh.face_page[faces]],
        pixels,
        np.ascontiguousarray(new_uvs[faces], dtype=np.float64),
        new_local[new_face_page[faces]],
        out_sizes,
        normal_map=normal_map,
        padding=options.padding,
        progress=progress,
        cancel=cancel,
    )
    del pixels
    # The first source of the role names the output and gives its format.
    first = sources[0]
    out = []
    for q_local, arr in enumerate(baked):
        out.append(OutputImage(page=int(new_pages[q_local]), role=role, source=maps[0].image,
                               pixels=np.asarray(arr), colorspace=first.colorspace,
                               is_float=first.is_float, alpha_mode=first.alpha_mode))
    return out


def loop_uvs(tri_loops: np.ndarray, uvs: np.ndarray, n_loops: int,
             fallback: Optional[np.ndarray] = None) -> Tuple[np.ndarray, int]:
    """Per-loop UVs (L, 2) from per-corner UVs; also the number of loops whose
    triangles disagree (a polygon split between charts keeps one of them)."""
    out = np.zeros((n_loops, 2), dtype=np.float64) if fallback is None else \
        np.array(fallback, dtype=np.float64).reshape(n_loops, 2)
    flat_loops = tri_loops.reshape(-1)
    flat_uv = uvs.reshape(-1, 2)
    out[flat_loops] = flat_uv  # last write wins for shared loops
    conflicts = np.abs(out[flat_loops] - flat_uv).max(axis=1) > 1e-6
    return out, int(len(np.unique(flat_loops[conflicts])))


def summary(report: dict) -> str:
    """One line for the Info log."""
    def num(key, fmt="{:.0f}"):
        v = report.get(key)
        return "?" if v is None else fmt.format(v)
    secs = report.get("seconds", {}).get("total")
    return (f"charts {num('charts_before')} -> {num('charts_after')}, "
            f"seam {num('seam_before', '{:.4g}')} -> {num('seam_after', '{:.4g}')}, "
            f"pages {num('pages_before')} -> {num('pages_after')}, "
            + (f"charts scaled to {num('scale', '{:.3g}')} of their texel density, " if report.get("shrunk") else "")
            + f"time {'?' if secs is None else f'{secs:.1f}'} s")
