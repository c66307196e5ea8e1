# SPDX-License-Identifier: MIT
"""read -> job -> write, shared by the operator, the Python entry and batch."""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Optional

import bpy
import numpy as np

from . import compat, job, read_bpy, write_bpy
from .options import BY_NAME
from .job import DefragCancelled, DefragError  # noqa: F401  (re-exported)

STORAGE = ("PACK", "SAVE")


@dataclass
class Settings:
    uv_map: Optional[str] = None  # None: the active map, or the one the image maps read (read_bpy.check_object)
    options: job.Options = field(default_factory=job.Options)
    storage: str = "PACK"  # 'PACK' into the .blend or 'SAVE' beside it (or in image_dir)
    image_dir: Optional[str] = None
    duplicate_materials: bool = False
    new_map_first: bool = True  # the new UV map at index 0 (FBX and game engines read that one)

    @classmethod
    def from_kwargs(cls, **kw) -> "Settings":
        opts = {name: kw.pop(name) for name in BY_NAME if name in kw}
        storage = str(kw.pop("storage", "PACK")).upper()
        s = cls(uv_map=_typed(kw.pop("uv_map", None), str, "uv_map") or None, options=job.Options(**opts),
                storage=storage, image_dir=kw.pop("image_dir", None),
                duplicate_materials=_typed(kw.pop("duplicate_materials", False), bool, "duplicate_materials"),
                new_map_first=_typed(kw.pop("new_map_first", True), bool, "new_map_first"))
        if kw:
            known = sorted(BY_NAME) + ["duplicate_materials", "image_dir", "new_map_first", "storage", "uv_map"]
            raise DefragError("unknown option(s): " + ", ".join(sorted(kw)) + " (known: " + ", ".join(known) + ")")
        s.validate()
        return s

    def validate(self) -> None:
        self.options.validate()
        if self.storage not in STORAGE:
            raise DefragError(f"storage must be one of {STORAGE}, not {self.storage!r}")
        if self.storage == "SAVE" and not self.image_dir and not bpy.data.filepath:
            raise DefragError("Save the .blend file first, or set Images to 'Pack in .blend'")


def _typed(value, kind: type, name: str):
    """value when it is of kind (or None), else DefragError: bool("no") would be True."""
    if value is not None and not isinstance(value, kind):
        raise DefragError(f"{name} must be a {kind.__name__}, not {value!r}")
    return value


def prepare(obj, settings: Settings, pixels_later: bool = False) -> read_bpy.ReadResult:
    """Validates and reads; raises DefragError. Changes nothing.
    pixels_later: the images' pixels are not read yet (read_bpy.PendingImage):
    the caller hands the job to a worker thread, then calls
    read_bpy.fetch_pixels on this thread, so that Blender reads them while
    the layout runs."""
    settings.validate()
    try:
        read = read_bpy.read(obj, settings.uv_map)
        if not pixels_later:
            for image in read.job.images.values():
                _ = image.pixels  # read here, on this thread; raises what failed
        return read
    except MemoryError as exc:
        raise DefragError("Out of memory while reading the mesh and images") from exc


@dataclass
class SharedRead:
    """Several objects read for one atlas shared by all: each object's read,
    the concatenated job and each object's faces in it."""

    reads: list
    job: job.JobInput
    faces: list


def prepare_shared(objects, settings: list, pixels_later: bool = False) -> SharedRead:
    """prepare() for every object (settings[k] for objects[k]), and the one
    job over all of them. Changes nothing."""
    reads = [prepare(obj, s, pixels_later) for obj, s in zip(objects, settings)]
    joined, faces = job.concatenate([r.job for r in reads])
    return SharedRead(reads=reads, job=joined, faces=faces)


def finish_shared(objects, shared: SharedRead, result: job.JobResult, settings: list):
    """finish() for every object of a shared atlas, in turn, yielding each
    report: the first writes the new images, the others rewire to them. The
    report's numbers are the shared job's; atlas_objects names every object."""
    images = write_bpy.SharedImages()
    names = [obj.name for obj in objects]
    in_common = _materials_in_common(shared.reads)
    for obj, read, faces, s in zip(objects, shared.reads, shared.faces, settings):
        if any(info.name in in_common for info in read.materials):
            # Each object rewires its materials to its own UV map and pages:
            # one material both rewired would keep the last object's only.
            s = replace(s, duplicate_materials=True)
        report = finish(obj, read, job.split(result, faces), s, shared_images=images)
        part = result.face_page[faces]
        report.update(atlas_objects=names, faces=faces.stop - faces.start,
                      pages_used=sorted(int(q) for q in np.unique(part[part >= 0])))
        yield report


def _materials_in_common(reads) -> set:
    """Names of the materials that several of the reads use."""
    seen, common = set(), set()
    for read in reads:
        names = {info.name for info in read.materials if info.page >= 0}
        common |= seen & names
        seen |= names
    return common


def shared_materials(objects, among_them: bool = True) -> set:
    """Names of the materials of the objects that objects drawing other
    meshes use, and (among_them) that several of the objects use. The
    objects duplicate them: the first object's rewiring would otherwise
    leave the others reading, and rendering, through a UV map they do not
    have. Objects drawing one of these meshes (linked duplicates) have it."""
    users = {}
    for obj in objects:
        for name in {slot.material.name for slot in obj.material_slots if slot.material}:
            users[name] = users.get(name, 0) + 1
    meshes = {obj.data for obj in objects}
    outside = {slot.material.name for o in bpy.data.objects if o.data not in meshes
               for slot in getattr(o, "material_slots", []) if slot.material}
    return {name for name, count in users.items() if count > 1 and among_them or name in outside}


def uses_any(obj, materials: set) -> bool:
    return any(slot.material and slot.material.name in materials for slot in obj.material_slots)


def compute(read: read_bpy.ReadResult, settings: Settings, progress=None, cancel=None,
            native=None) -> job.JobResult:
    """The native work: thread-safe (touches no bpy data)."""
    try:
        return job.run(read.job, settings.options, progress=progress, cancel=cancel, native=native)
    except MemoryError as exc:
        faces = len(read.job.mesh.triangles)
        raise DefragError(f"Out of memory while computing the new atlas of {faces:,} faces: free memory, "
                          "or lower density_scale or max_page_size if the output pages are large") from exc


def _set_mode(obj, mode: str) -> None:
    if obj.mode == mode:
        return
    ctx = bpy.context
    with compat.temp_override(ctx, active_object=obj, object=obj, edit_object=obj if mode != "EDIT" else None):
        bpy.ops.object.mode_set(mode=mode)


def finish(obj, read: read_bpy.ReadResult, result: job.JobResult, settings: Settings,
           shared_images=None) -> dict:
    """Writes the result (in Object mode, returning to the mode it found);
    shared_images: see write_bpy.write."""
    t0 = time.perf_counter()
    mode = obj.mode
    try:
        _set_mode(obj, "OBJECT")
        written = write_bpy.write(obj, read, result, storage=settings.storage,
                                  image_dir=settings.image_dir,
                                  duplicate_materials=settings.duplicate_materials,
                                  new_map_first=settings.new_map_first, shared=shared_images)
    finally:
        if obj.mode != mode:
            _set_mode(obj, mode)
    report = plain(result.report)
    report.setdefault("seconds", {})["write"] = time.perf_counter() - t0
    report["object"] = obj.name
    report["source_uv_map"] = read.uv_map
    report.update(written)
    report["warnings"] = (list(result.report.get("warnings", [])) + list(read.warnings)
                          + list(written.get("warnings", [])))
    return report


def defragment(obj, progress=None, cancel=None, wait_in_main_thread=False, **options) -> dict:
    """Defragments obj's texture atlas synchronously; returns the report dict.

    Options: those of options.SCHEMA, and uv_map (default: the active one, or
    the one the image maps read), storage ('PACK' | 'SAVE'), image_dir,
    duplicate_materials (default: as the operator, copies of all of obj's
    materials when any is used by an object drawing another mesh, which
    would otherwise read a UV map it lacks), new_map_first. The
    report's 'shrunk' (and a warning) says when charts lost texel density to
    fit max_page_size, max_pages or the input's texel count. Raises DefragError
    (a subclass of Exception) with the reason; on any error nothing is changed.
    wait_in_main_thread: the native work runs on a thread of its own while
    this thread reads the images' pixels (the layout needs only their sizes;
    seconds 'read_pixels' in the report), then waits in short steps, free to
    run signal handlers (the batch entry's SIGINT cancels the token).
    """
    with as_defrag_error():
        settings = Settings.from_kwargs(**options)
        t0 = time.perf_counter()
        read = prepare(obj, settings, pixels_later=wait_in_main_thread)
        if options.get("duplicate_materials") is None:  # obj is a mesh object: prepare checked it
            settings = replace(settings, duplicate_materials=uses_any(obj, shared_materials([obj])))
        t_read = time.perf_counter() - t0
        fetched = {}
        if wait_in_main_thread:
            def fetch_pixels():  # here, while the layout runs on the worker
                t = time.perf_counter()
                read_bpy.fetch_pixels(read.job)
                fetched["read_pixels"] = time.perf_counter() - t
            result = on_worker_thread(compute, read, settings, progress=progress, cancel=cancel,
                                      meanwhile=fetch_pixels)
        else:
            result = compute(read, settings, progress=progress, cancel=cancel)
        report = finish(obj, read, result, settings)
    report["seconds"].update(read=t_read, **fetched)
    return report


def on_worker_thread(fn, *args, each_step=None, meanwhile=None, **kwargs):
    """fn(*args, **kwargs) on another thread, joined in 50 ms steps, after
    each of which this thread calls each_step() (if given: bpy work such as
    showing progress belongs here, not in fn); meanwhile() (if given) runs
    on this thread once the worker has started; fn's exception is raised here."""
    outcome = {}

    def work():
        try:
            outcome["value"] = fn(*args, **kwargs)
        except BaseException as exc:  # handed to the waiting thread
            outcome["error"] = exc

    worker = threading.Thread(target=work, name="atlas_defrag", daemon=True)
    worker.start()
    if meanwhile is not None:
        meanwhile()
    while worker.is_alive():
        worker.join(0.05)
        if each_step is not None:
            each_step()
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


@contextlib.contextmanager
def as_defrag_error():
    """Raises what escapes the block as DefragError, the cause kept
    (__cause__): a wrong argument type, a file that cannot be written, an
    image Blender could not save or load (bpy raises RuntimeError)."""
    try:
        yield
    except DefragError:
        raise
    except OSError as exc:
        where = f" ({exc.filename})" if exc.filename else ""
        raise DefragError(f"Could not read or write a file{where}: {exc.strerror or exc}") from exc
    except (TypeError, ValueError) as exc:
        raise DefragError(f"Bad argument: {exc}") from exc
    except RuntimeError as exc:
        raise DefragError(f"Blender refused: {exc}") from exc


def plain(value):
    """Numpy scalars and arrays to JSON-friendly Python values."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value
