"""Defragments a scan's atlas without Blender and prints what changed.

    PYTHONPATH=build/addon .venv/bin/python tools/defrag_scan.py IN.obj|IN.gltf|IN.glb|IN.ply OUT_DIR [options]

Runs the add-on's job (atlas_defrag.job.run, the same layout and bake as in
Blender), writes OUT_DIR/<name>_defrag.obj + <name>_defrag.mtl + one
<name>_defrag_page<P>_<map>.png per page and map, and
prints charts, seam length, texels and seconds per stage (--metrics adds
flips, overlap, density loss and PSNR, measured independently of the job).
The other options are those of the add-on (--help lists them). This entry
exists for machines and pipelines without Blender.
"""
from __future__ import annotations

import argparse
import glob
import os
import re
import shutil
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import scan_io  # beside this file

# The add-on's bpy-free modules: from PYTHONPATH (scripts/demo.sh sets it), else from this checkout's build.
sys.path.append(str(Path(__file__).resolve().parent.parent / "build" / "addon"))
try:
    from atlas_defrag import _native, job, made_folders, options, png_files
except ImportError as exc:
    sys.exit(f"defrag_scan: {exc}: build the module (cmake --build build) and put its folder "
             "on the path: PYTHONPATH=build/addon")


def progress_line(stage: str, fraction: float) -> None:
    """One self-overwriting status line, on terminals only (logs stay clean)."""
    if sys.stderr.isatty():
        print(f"\r  {stage:<10} {fraction:6.1%}\x1b[K", end="", file=sys.stderr, flush=True)  # K: clears the rest


# MTL statements of the maps an MTL can name; a metallic-roughness map (two
# channels of one image) has none.
MTL_MAPS = {"base_color": "map_Kd", "normal": "norm", "occlusion": "map_ao", "emission": "map_Ke"}


def write_obj(path: Path, scan, uvs: np.ndarray, face_page: np.ndarray, maps: list[dict]) -> list[str]:
    """One vt per face corner keeps the writer trivial; importers weld them back.
    The OBJ text is written natively (_native.write_obj) while the maps' PNGs
    are encoded side by side (png_files, as the add-on does). Returns the
    images written that the MTL does not name."""
    stem = path.stem
    images, unnamed = [], []
    with open(path.with_suffix(".mtl"), "w") as mtl:
        mtl.write("newmtl untextured\nKd 0.8 0.8 0.8\n")  # faces without a page use it
        for page, roles in enumerate(maps):
            mtl.write(f"newmtl page{page}\nKd 1 1 1\n")
            for role, image in roles.items():
                name = f"{stem}_page{page}_{role}.png"
                images.append((path.parent / name, image))
                if role in MTL_MAPS:
                    mtl.write(f"{MTL_MAPS[role]} {name}\n")
                else:
                    unnamed.append(name)
    with ThreadPoolExecutor(max_workers=1) as pool:
        pngs = pool.submit(png_files.write_pngs, images)
        # Material 0 is "untextured" (page -1), material p + 1 is page p.
        _native.write_obj(str(path), f"{stem}.mtl", scan.positions, scan.triangles, uvs, face_page + 1,
                          ["untextured"] + [f"page{p}" for p in range(len(maps))], scan.normals, scan.normal_index)
        pngs.result()
    return unnamed


def read_texture(read, source, label: str):
    """read(source) (scan_io.load_image or image_size), its failures (a file
    cut short, bytes no decoder knows) as DefragError naming the image."""
    try:
        return read(source)
    except (OSError, ValueError, SyntaxError) as exc:  # Pillow raises SyntaxError on some broken files
        raise job.DefragError(f"cannot read the texture {label}: {exc}") from exc


def decoded(source, label: str) -> np.ndarray:
    return read_texture(scan_io.load_image, source, label)


class DecodingImage:
    """A job.ImageData whose pixels a background thread decodes: the layout
    needs only the image's size (from its header), so it runs meanwhile and
    only the bake waits for the pixels."""

    def __init__(self, name: str, source, colorspace: str, pool: ThreadPoolExecutor):
        self.name, self.colorspace, self.is_float, self.alpha_mode = name, colorspace, False, "STRAIGHT"
        label = source_label(source, name)
        self.size = read_texture(scan_io.image_size, source, label)
        self._pixels = pool.submit(decoded, source, label)

    @property
    def pixels(self) -> np.ndarray:
        return self._pixels.result()


def source_label(source, name: str) -> str:
    return str(source) if isinstance(source, Path) else f"{name} (embedded)"


def job_input(scan, pool: ThreadPoolExecutor = None) -> job.JobInput:
    """The scan as the add-on's job takes it: one image map per page and role,
    decoded on pool (or here and now without one); pages with the same roles
    form one material group, as read_bpy groups them."""
    images, pages, groups = {}, [], {}
    for p, roles in enumerate(scan.maps):
        maps = []
        for role in sorted(roles, key=job.role_sort_key):
            name, colorspace = f"page{p}_{role}", "sRGB" if role == "base_color" else "Non-Color"
            images[name] = (DecodingImage(name, roles[role], colorspace, pool) if pool else
                            job.ImageData(name, decoded(roles[role], source_label(roles[role], name)),
                                          colorspace=colorspace))
            maps.append(job.ImageMap(role, name, normal_map=role == "normal"))
        pages.append(job.SourcePage(maps, groups.setdefault(tuple(m.role for m in maps), len(groups))))
    mesh = job.MeshData(scan.positions, scan.triangles, scan.uvs, scan.face_page)
    return job.JobInput(mesh, pages, images)


def page_maps(result: job.JobResult) -> list[dict]:
    """Per new page: {role: pixels}."""
    maps = [dict() for _ in result.page_sizes]
    for image in result.images:
        maps[image.page][image.role] = image.pixels
    return maps


def colours(inp: job.JobInput, result: job.JobResult):
    """(old, new): the base colour of every source and new page, RGB."""
    def rgb(pixels):
        return np.ascontiguousarray(pixels[:, :, :3])
    old = [rgb(inp.images[page.map_for("base_color").image].pixels) for page in inp.pages]
    new = [rgb(result.image_for(q, "base_color").pixels) for q in range(len(result.page_sizes))]
    return old, new


def measure_input(scan) -> dict:
    """The scan's own atlas as measure gives it ("old"): it needs no result, so
    it runs beside the job."""
    return _native.measure_atlas(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes)


def quality(scan, inp: job.JobInput, result: job.JobResult, old: dict = None):
    """(measure, compare_colors) of the new atlas against the scan's: flips,
    texels covered twice, density loss and colour PSNR. old: measure_input's
    figures, if measured already."""
    m = _native.measure(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                        result.uvs, result.face_page, result.page_sizes, with_old=old is None)
    if old is not None:
        m["old"] = old
    old_colour, new_colour = colours(inp, result)
    fidelity = _native.compare_colors(scan.positions, scan.triangles, scan.uvs, scan.face_page, old_colour,
                                      result.uvs, result.face_page, new_colour)
    return m, fidelity


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("--metrics", action=argparse.BooleanOptionalAction, default=False,
                        help="also measure the quality figures (flips, texels covered twice, density loss, "
                             "colour PSNR) while the files are written, at some cost in time (bench/RESULTS.md; "
                             "default: off)")
    options.add_arguments(parser)
    args = options.parsed(parser, argv)
    if args.input.suffix.lower() not in scan_io.SCAN_EXTS:
        parser.error(f"unsupported scan format '{args.input.suffix}' (use {', '.join(scan_io.SCAN_EXTS)})")
    return args


def folder_problem(folder: Path) -> str:
    """Why OUT_DIR could not take the files ('' if it can), before the work."""
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        return f"{probe} is not a folder"
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"{probe} is not writable"
    return ""


def output_files(folder: Path, stem: str, maps: list[dict]) -> list[Path]:
    """What write_obj writes: the OBJ, its MTL and one PNG per page and map."""
    names = [f"{stem}.obj", f"{stem}.mtl"] + [f"{stem}_page{p}_{role}.png" for p, roles in enumerate(maps)
                                                for role in roles]
    return [folder / n for n in names]


def stale_pages(folder: Path, stem: str, outputs: list[Path], inputs: list[Path]) -> list[Path]:
    """PNGs named as write_obj names its pages, left in folder by an earlier
    run with more pages or maps than this one writes: the model written
    would no longer name them. Input files are never among them."""
    keep = {os.path.realpath(p) for p in list(outputs) + list(inputs)}
    roles = "|".join(sorted(set(MTL_MAPS) | {"metallic_roughness"}))
    named = re.compile(re.escape(stem) + rf"_page\d+_({roles})\.png")
    return sorted(p for p in folder.glob(glob.escape(stem) + "_page*.png")
                  if named.fullmatch(p.name) and p.is_file() and not p.is_symlink()
                  and os.path.realpath(p) not in keep)


def refuse_overwriting_input(outputs: list[Path], inputs: list[Path]) -> None:
    """Failed naming the input file an output would replace, if any."""
    read = {os.path.realpath(p) for p in inputs}
    replaced = next((str(p) for p in outputs if os.path.realpath(p) in read), "")
    if replaced:
        raise Failed(f"writing would replace the input file {replaced}: choose another OUT_DIR")


class Failed(Exception):
    """Ends the run with its message on stderr and exit code 1."""


def load_checked(args):
    """The scan, once OUT_DIR is known to be able to take the files."""
    try:
        scan = scan_io.load(args.input)
    except (OSError, ValueError) as exc:
        raise Failed(f"cannot read {args.input}: {exc}") from exc
    problem = folder_problem(args.output)
    if problem:
        raise Failed(f"cannot write into {args.output}: {problem}")
    # The OBJ and MTL names are known before the work, the PNGs' once the pages are.
    refuse_overwriting_input(output_files(args.output, f"{args.input.stem}_defrag", []), scan.files)
    for warning in scan.warnings:
        print(f"defrag_scan: warning: {warning}", file=sys.stderr)
    return scan


def run_job(args, scan):
    """(job input, result, the input atlas's measures pending or None). The
    images decode without the GIL (libdeflate and row filters, natively, for PNGs,
    Pillow for the others), beside the layout, and the input's own atlas is
    measured after that, where the layout leaves a core idle."""
    chosen = job.Options(**{o.name: getattr(args, o.name) for o in options.SCHEMA})
    with ThreadPoolExecutor(max_workers=1) as decoder:
        try:
            inp = job_input(scan, decoder)
            old = decoder.submit(measure_input, scan) if args.metrics else None
            result = job.run(inp, chosen, progress=progress_line, native=_native)
        except (job.DefragError, OSError, ValueError, SyntaxError) as exc:  # SyntaxError: Pillow's, on bad headers
            raise Failed(str(exc)) from exc
    if sys.stderr.isatty():
        print(file=sys.stderr)
    return inp, result, old


def every_instance(result: job.JobResult, rows) -> tuple:
    """(uvs, face_page) of every face of the scan read, each instance of a
    mesh with its first's (rows: see Scan.first_instances; None: as laid out)."""
    if rows is None:
        return result.uvs, result.face_page
    return result.uvs.reshape(-1, 2)[rows], result.face_page[rows[:, 0] // 3]


def write_checked(args, scan, laid, rows, inp, result, old):
    """Writes the files, never over one the scan was read from, into a
    scratch folder in OUT_DIR first and then into place, the OBJ last: a run
    that fails leaves an earlier run's files as they were. Returns the
    metrics of the faces laid out (measured natively without the GIL, beside
    the writing) or (None, None), and the images the MTL does not name.
    laid, rows: see Scan.first_instances; every face is written with its
    source's new UVs."""
    maps = page_maps(result)
    outputs = output_files(args.output, f"{args.input.stem}_defrag", maps)
    refuse_overwriting_input(outputs, scan.files)
    with ThreadPoolExecutor(max_workers=1) as pool:
        measured = pool.submit(quality, laid, inp, result, old.result()) if args.metrics else None
        made, scratch, written = made_folders.missing(args.output), None, False
        try:
            args.output.mkdir(parents=True, exist_ok=True)
            scratch = Path(tempfile.mkdtemp(prefix=SCRATCH_PREFIX, dir=args.output))
            unnamed = write_obj(scratch / outputs[0].name, scan, *every_instance(result, rows), maps)
            stale = stale_pages(args.output, f"{args.input.stem}_defrag", outputs, scan.files)
            swap_in(scratch, outputs[1:] + outputs[:1], stale)
            written = True
        except OSError as exc:
            raise Failed(f"writing into {args.output} failed: {exc}") from exc
        finally:  # Ctrl-C and encoder errors too: nothing half written is left, nor folders made for it
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
            if not written:
                made_folders.remove_empty(made)
        return (measured.result() if measured else (None, None)), unnamed


SCRATCH_PREFIX = ".defrag_scan_"
SET_ASIDE = ".replaced"


def interrupted_runs(folder: Path) -> list[str]:
    """Warnings naming the scratch folders in which a run killed while
    moving its files in (see swap_in) left the files it had replaced: they
    stay there for the user, and the outputs beside them may mix both runs."""
    warnings = []
    for kept in sorted(folder.glob(f"{SCRATCH_PREFIX}*/{SET_ASIDE}")):
        try:
            names = sorted(p.name for p in kept.iterdir())
        except OSError:
            continue
        if names:
            warnings.append(f"{kept} holds files of an earlier output that an interrupted run replaced "
                            f"({', '.join(names)}): left as they are; the files in {folder} may mix both runs")
    return warnings


def swap_in(scratch: Path, outputs: list[Path], stale: list[Path] = ()) -> None:
    """Moves the files of these names from scratch over outputs, in order,
    then the stale files out of the way. The files they replace and the
    stale ones wait in scratch until all are in; when a move of an output
    fails (or is interrupted), every output is put back as it was. A stale
    file that cannot be moved (held open, say) stays."""
    kept = scratch / SET_ASIDE
    kept.mkdir()
    done = []  # (output, whether an earlier file was kept), as far as the moves went
    try:
        for path in outputs:
            had = os.path.lexists(path)
            if had:
                os.replace(path, kept / path.name)
            done.append((path, had))
            os.replace(scratch / path.name, path)
    except BaseException:
        for path, had in reversed(done):
            if had:
                os.replace(kept / path.name, path)
            elif os.path.lexists(path):
                os.remove(path)
        raise
    for path in stale:
        try:
            os.replace(path, kept / path.name)
        except OSError:
            pass


def main(argv=None) -> int:
    args = parse_args(argv)
    t0 = time.perf_counter()
    try:
        scan = load_checked(args)
        t_load = time.perf_counter() - t0
        laid, rows = scan.first_instances()  # a mesh several nodes draw is laid out once
        inp, result, old = run_job(args, laid)
        interrupted = interrupted_runs(args.output)  # before this run's own scratch folder
        (m, fidelity), unnamed = write_checked(args, scan, laid, rows, inp, result, old)
    except Failed as exc:
        print(f"defrag_scan: error: {exc}", file=sys.stderr)
        return 1
    repeated = scan.instances_repeated()
    print(f"{args.input.name}: {len(scan.triangles)} faces" + (
        f" ({repeated} of them in further instances of a mesh, laid out once with its first)" if repeated else ""))
    print_report(result, m, fidelity, t_load)
    print(f"  written to    {args.output}")
    for warning in result.report.get("warnings", []) + interrupted:
        print(f"defrag_scan: warning: {warning}", file=sys.stderr)
    if unnamed:
        print(f"defrag_scan: warning: {', '.join(unnamed)} written, but the MTL does not name "
              "them: an MTL has no metallic-roughness map", file=sys.stderr)
    return 0


def print_report(result: job.JobResult, m: dict, fidelity: dict, t_load: float) -> None:
    r = result.report
    print(f"  charts        {r['charts_before']} -> {r['charts_after']} (aggregated {r['charts_aggregated']}, "
          f"split back: {r['splits_overlap']} overlap, {r['splits_density']} density, {r['splits_solver']} solver, "
          f"{r['splits_not_disk']} topology; lone charts overlapping themselves halved: {r['overlap_halved']}; "
          f"relief cuts: {r['relief_cuts']}; "
          f"density repairs: {r['density_repaired']}; holes of the mesh filled: {r['holes_filled']})")
    stops = ", ".join(f"{reason} {n}" for reason, n in r["aggregate_stops"].items() if n)
    print(f"  merges left   {stops or 'none'} (adjacent chart pairs, by what refused them)")
    print(f"  energy        median {r['energy_initial_median']:.2f} -> {r['energy_median']:.3f}, max {r['energy_max']:.2f} "
          f"over {r['charts_solved']} flattened charts (4 = isometric)")
    print(f"  seam length   {r['seam_before']:.1f} -> {r['seam_after']:.1f} (3D length / sqrt(area); "
          f"refinement moved {r['refine_faces_moved']} faces, removing {r['refine_seam_removed']:.2f}; "
          f"{r['packing_cuts']} cuts for packing added {r['packing_cut_seam']:.2f}"
          f"{', to stay within the input texels' if r['cut_to_fit'] else ''})")
    print(f"  density rule  {r['density_reflattened']} charts flattened again to keep the surface's loss in budget; "
          f"{r['faces_detached']} faces made charts of their own (float32 would turn them over)")
    print(f"  texels        {r['texels_before']:,} -> {r['texels_after']:,} "
          f"(packing efficiency {r['packing_efficiency']:.1%}, scale {r['scale']:.3f}"
          f"{', SHRUNK below the density asked for' if r['shrunk'] else ''}; pages {result.page_sizes.tolist()}, "
          f"padding {r['padding']})")
    print(f"  copied        {r['copied_share']:.1%} of the covered texels taken unresampled from the old atlas")
    detail = job.detail_text(r)
    if detail:
        print(f"  colour guard  {detail}; option min_colour_psnr")
    if m is not None:
        print(f"  flipped       {m['old']['flipped_faces']} -> {m['new']['flipped_faces']}; "
              f"texels shared by two triangles {m['old']['overlap_texels']} -> {m['new']['overlap_texels']}")
        print(f"  density loss  {m['map']['density_loss_area_share']:.2%} of the area below half its texel density")
        print(f"  colour        PSNR {fidelity['psnr_db']:.1f} dB (clean {fidelity['psnr_clean_db']:.1f}, border "
              f"{fidelity['psnr_border_db']:.1f}, {fidelity['clean_share']:.0%} clean), "
              f"{fidelity['share_off_32']:.2%} of points off by > 32/255")
    stages = ", ".join(f"{k} {v:.2f}" for k, v in r["seconds"].items() if k != "total")
    print(f"  seconds       load {t_load:.2f}, {stages}")


if __name__ == "__main__":
    sys.exit(main())
