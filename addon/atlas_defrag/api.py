# SPDX-License-Identifier: MIT
"""read -> job -> write, shared by the operator, the Python entry and batch."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Optional

import bpy

from . import compat, job, read_bpy, write_bpy
from .options import BY_NAME
from .job import DefragCancelled, DefragError  # noqa: F401  (re-exported)

STORAGE = ("PACK", "SAVE")


@dataclass
class Settings:
    uv_map: Optional[str] = None  # None: the active UV map
    options: job.Options = field(default_factory=job.Options)
    storage: str = "PACK"  # 'PACK' into the .blend or 'SAVE' beside it (or in image_dir)
    image_dir: Optional[str] = None
    duplicate_materials: bool = False
    new_map_first: bool = True  # the new UV map at index 0 (FBX and game engines read that one)

    @classmethod
    def from_kwargs(cls, **kw) -> "Settings":
        opts = {name: kw.pop(name) for name in BY_NAME if name in kw}
        storage = str(kw.pop("storage", "PACK")).upper()
        s = cls(uv_map=kw.pop("uv_map", None) or None, options=job.Options(**opts),
                storage=storage, image_dir=kw.pop("image_dir", None),
                duplicate_materials=bool(kw.pop("duplicate_materials", False)),
                new_map_first=bool(kw.pop("new_map_first", True)))
        if kw:
            raise TypeError("unknown option(s): " + ", ".join(sorted(kw)))
        s.validate()
        return s

    def validate(self) -> None:
        self.options.validate()
        if self.storage not in STORAGE:
            raise DefragError(f"storage must be one of {STORAGE}, not {self.storage!r}")
        if self.storage == "SAVE" and not self.image_dir and not bpy.data.filepath:
            raise DefragError("Save the .blend file first, or set Images to 'Pack in .blend'")


def prepare(obj, settings: Settings) -> read_bpy.ReadResult:
    """Validates and reads; raises DefragError. Changes nothing."""
    settings.validate()
    try:
        return read_bpy.read(obj, settings.uv_map)
    except MemoryError as exc:
        raise DefragError("Out of memory while reading the mesh and images") from exc


def compute(read: read_bpy.ReadResult, settings: Settings, progress=None, cancel=None,
            native=None) -> job.JobResult:
    """The native work: thread-safe (touches no bpy data)."""
    try:
        return job.run(read.job, settings.options, progress=progress, cancel=cancel, native=native)
    except MemoryError as exc:
        raise DefragError("Out of memory: try a smaller page size or maximum page size") from exc


def _set_mode(obj, mode: str) -> None:
    if obj.mode == mode:
        return
    ctx = bpy.context
    with compat.temp_override(ctx, active_object=obj, object=obj, edit_object=obj if mode != "EDIT" else None):
        bpy.ops.object.mode_set(mode=mode)


def finish(obj, read: read_bpy.ReadResult, result: job.JobResult, settings: Settings) -> dict:
    """Writes the result (in Object mode, returning to the mode it found)."""
    t0 = time.perf_counter()
    mode = obj.mode
    try:
        _set_mode(obj, "OBJECT")
        written = write_bpy.write(obj, read, result, storage=settings.storage,
                                  image_dir=settings.image_dir,
                                  duplicate_materials=settings.duplicate_materials,
                                  new_map_first=settings.new_map_first)
    finally:
        if obj.mode != mode:
            _set_mode(obj, mode)
    report = plain(result.report)
    report.setdefault("seconds", {})["write"] = time.perf_counter() - t0
    report["object"] = obj.name
    report["source_uv_map"] = read.uv_map
    report.update(written)
    report["warnings"] = list(read.warnings) + list(written.get("warnings", []))
    return report


def defragment(obj, progress=None, cancel=None, **options) -> dict:
    """Defragments obj's texture atlas synchronously; returns the report dict.

    Options: those of options.SCHEMA, and uv_map (default: active), storage
    ('PACK' | 'SAVE'), image_dir, duplicate_materials, new_map_first. Raises DefragError (a
    subclass of Exception) with the reason; on any error nothing is changed.
    """
    settings = Settings.from_kwargs(**options)
    t0 = time.perf_counter()
    read = prepare(obj, settings)
    t_read = time.perf_counter() - t0
    result = compute(read, settings, progress=progress, cancel=cancel)
    report = finish(obj, read, result, settings)
    report["seconds"]["read"] = t_read
    return report


def plain(value):
    """Numpy scalars and arrays to JSON-friendly Python values."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if np is not None:
        if isinstance(value, np.ndarray):
            return value.tolist()
        if isinstance(value, np.generic):
            return value.item()
    return value
