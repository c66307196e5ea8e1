"""Reads textured scans (OBJ+MTL, glTF, GLB, PLY) into plain numpy arrays, without Blender.

Used by the tests, the benchmark and the command-line demo; the add-on reads
meshes through bpy instead. Polygons are fan-triangulated (OBJ by the native
reader, _native.read_obj; PLY by the add-on's ply_io), because the native stages take
triangles only.
"""
from __future__ import annotations

import base64
import io
import json
import os
import re
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Scan:
    positions: np.ndarray          # (V, 3) float64
    triangles: np.ndarray          # (F, 3) int32
    uvs: np.ndarray                # (F, 3, 2) float64, page units, v up
    face_page: np.ndarray          # (F,) int32, -1 for faces without texture
    page_sizes: np.ndarray         # (P, 2) int32, width and height
    page_images: list = field(default_factory=list)  # per page: Path or bytes of the base colour image
    maps: list = field(default_factory=list)         # per page: {role: Path or bytes}
    files: list = field(default_factory=list)        # every file read (model, MTL, buffers, textures)
    warnings: list = field(default_factory=list)     # what was read otherwise than asked (textures missing)
    # (F, 3) int64 or None: per face corner, the corner (3 * face + k) whose
    # UVs it repeats, its own where it repeats none. A glTF mesh drawn by
    # several nodes is read once per node; its later instances repeat the
    # first, whose UVs they share in the file and so must share in the output.
    corner_source: np.ndarray = None
    # Shading normals, written back as read (the job moves no vertex):
    # normal_index (F, 3) rows into normals (N, 3), -1 on a face without
    # them; both None when the scan has none.
    normals: np.ndarray = None
    normal_index: np.ndarray = None

    def instances_repeated(self) -> int:
        """How many faces repeat another's UVs (later instances of a mesh)."""
        if self.corner_source is None:
            return 0
        return int((self.corner_source[:, 0] // 3 != np.arange(len(self.triangles))).sum())

    def first_instances(self) -> tuple["Scan", np.ndarray]:
        """(scan of the faces that repeat none, (F, 3) rows into its corners
        (3 * its face + k) giving every corner of this scan its source):
        `new_uvs.reshape(-1, 2)[rows]` lays every instance out as the first.
        (self, None) when no face repeats another."""
        if self.instances_repeated() == 0:
            return self, None
        faces = np.arange(len(self.triangles))
        source = self.corner_source
        kept = np.flatnonzero(source[:, 0] // 3 == faces)
        position = np.full(len(faces), -1, dtype=np.int64)
        position[kept] = np.arange(len(kept))
        rows = position[source // 3] * 3 + source % 3
        first = Scan(self.positions, self.triangles[kept], self.uvs[kept], self.face_page[kept], self.page_sizes,
                     self.page_images, self.maps, self.files, self.warnings)
        return first, rows


def _open_image(source):
    """PIL.Image.open of a path or of bytes. For bytes in no format Pillow
    knows, its UnidentifiedImageError names only its stream object: the
    error raised instead says what was not recognised."""
    from PIL import Image, UnidentifiedImageError

    Image.MAX_IMAGE_PIXELS = None  # scans routinely exceed Pillow's bomb guard
    in_memory = isinstance(source, (bytes, bytearray))
    try:
        return Image.open(io.BytesIO(source) if in_memory else source)
    except UnidentifiedImageError:
        what = "the image's bytes are" if in_memory else f"{source} is"
        raise UnidentifiedImageError(f"{what} in no image format this reader decodes (PNG, JPEG, WebP, TIFF, ...)"
                                     ) from None


def load_image(source) -> np.ndarray:
    """(H, W, C) uint8 with row 0 at the bottom (v = 0), as Blender stores
    pixels; C is 1 (grey), 3 or 4. 8-bit RGB and RGBA PNGs are decoded as the
    add-on decodes them (png_files.decode_png: libdeflate, then the row
    filters undone natively straight into Blender's row order, skipping Pillow's copy
    into numpy and the flip); other files, and PNGs it refuses, by Pillow."""
    from atlas_defrag import png_files

    data = bytes(source) if isinstance(source, (bytes, bytearray)) else Path(source).read_bytes()
    pixels = png_files.decode_png_or_none(data)
    if pixels is not None:
        return pixels
    if data.startswith(png_files.SIGNATURE) and not png_files.critical_crcs_hold(data):
        raise ValueError("a critical chunk of the PNG fails its CRC (libpng, so Blender, refuses it)")
    img = _open_image(data)
    if img.mode.startswith("I;16") or img.mode == "I":  # 16-bit grey: Pillow's convert would clip it
        pixels = (np.asarray(img).astype(np.uint32) >> 8).clip(0, 255).astype(np.uint8)[::-1]
        return np.ascontiguousarray(pixels[..., None])
    keyed = "transparency" in img.info  # a tRNS chunk: palette or colour-key alpha, as Blender reads it
    if img.mode not in ("L", "RGB", "RGBA") or keyed:
        img = img.convert("RGBA" if "A" in img.getbands() or keyed else "RGB")
    pixels = np.asarray(img)[::-1]
    return np.ascontiguousarray(pixels[..., None] if pixels.ndim == 2 else pixels)


def _refuse_beyond_memory(size: tuple[int, int], name: str):
    """ValueError when a header claims more pixels than half this machine's
    memory holds at 4 bytes each: the layout would scale its charts to that
    page, and decoding would exhaust memory before the file's end showed the
    claim false."""
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows): the decoder's own MemoryError stands
        return
    needed = 4 * size[0] * size[1]
    if needed > memory / 2:
        raise ValueError(f"the texture {name} claims {size[0]} x {size[1]} pixels ({needed / 2**30:.1f} GB decoded), "
                         f"more than half of this machine's {memory / 2**30:.0f} GB of memory")


def image_size(source) -> tuple[int, int]:
    """(width, height) from the header; ValueError when decoding those pixels
    would take more than half this machine's memory."""
    in_memory = isinstance(source, (bytes, bytearray))
    with _open_image(source) as img:
        _refuse_beyond_memory(img.size, "in the file" if in_memory else str(source))
        return img.size


# The command line writes positions, UVs and the baked maps; in Blender
# the mesh keeps its other attributes.
_VERTEX_COLOURS = ("the mesh has vertex colours, which the command line does not write "
                   "(in Blender they stay on the mesh)")


SCAN_EXTS = (".obj", ".gltf", ".glb", ".ply")


def load(path) -> Scan:
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        scan = load_obj(path)
    elif suffix == ".glb" or (suffix == ".gltf" and _starts_as_glb(path)):
        scan = load_glb(path)
    elif suffix == ".gltf":
        scan = load_gltf(path)
    elif suffix == ".ply":
        scan = load_ply(path)
    else:
        raise ValueError(f"unsupported scan format: {path.suffix} (OBJ, glTF, GLB or PLY)")
    scan.warnings += _sixteen_bit_warnings(scan)
    return scan


def _sixteen_bit_warnings(scan: Scan) -> list:
    """Maps with more than 8 bits a channel (16-bit PNG or TIFF, OpenEXR,
    HDR; image_headers' float_pixels, as Blender holds them): decoded to 8
    here, as they will be written."""
    from atlas_defrag import image_headers

    out = []
    for page, maps in enumerate(scan.maps):
        for role, source in maps.items():
            with io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else open(source, "rb") as f:
                claim = image_headers.claimed_size(f, str(source) if isinstance(source, Path) else "")
            if claim is not None and claim.float_pixels:
                name = source.name if isinstance(source, Path) else f"page {page}"
                out.append(f"the {role} map {name} has 16 bits a channel or more: it is read and written with 8")
    return out


def _starts_as_glb(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(4) == b"glTF"


# ---- OBJ ------------------------------------------------------------------

def _material_libraries(obj_path: Path, mtllibs: list[str]) -> tuple[list[Path], list[str]]:
    """(the MTL files of an OBJ that are there, the libraries named that are
    not). Each mtllib statement names one file, whose name may hold spaces,
    or several (the OBJ format allows both); its words from one starting with
    `#` on are a comment. A statement none of whose readings is there is
    missing as a whole; one that names files some of which are there misses
    the other .mtl names."""
    from atlas_defrag import mtl_text
    found, missing = [], []
    for lib in mtllibs:
        whole = obj_path.parent / mtl_text.unquoted(lib).replace("\\", "/")
        if whole.is_file():
            found.append(whole)
            continue
        words = [quoted or bare for quoted, bare in re.findall(r'"([^"]*)"|(\S+)', lib)]
        words = words[:next((i for i, w in enumerate(words) if w.startswith("#")), len(words))]
        paths = [obj_path.parent / w.replace("\\", "/") for w in words if w]
        present = [p for p in paths if p.is_file()]
        found += present
        missing += [p.name for p in paths if p not in present and p.suffix.lower() == ".mtl"] if present else [lib]
    return found, missing


def _texture_path(reference: str, folders: list[Path]) -> Path:
    """The file a map_Kd statement names: its arguments after the options,
    with a trailing comment or only the last word as fallbacks (older writers
    never quoted names), relative to the MTL's folder, then the OBJ's; a path
    from another machine (C:\\...\\textures\\t.jpg) by its trailing folders
    there, longest first, down to its file name (textures/t.jpg, then t.jpg)."""
    from atlas_defrag import mtl_text

    whole = mtl_text.unquoted(mtl_text.map_file(reference)).replace("\\", "/")
    names = [whole, whole.split(" #")[0].strip(), whole.split()[-1] if whole.split() else ""]
    names += [n.split("/", k)[-1] for n in names for k in range(1, n.count("/") + 1)]
    for name in filter(None, names):
        for folder in folders:
            if (folder / name).is_file():
                return folder / name
    return folders[0] / whole


# The MTL map statements this reader carries over, by the role the job gives
# their image. Blender's OBJ importer reads map_Bump and bump as a normal map,
# and so does this reader where the image has colour (a grey one is a height
# map); map_ao and map_Ke are how the command-line entry writes occlusion and
# emission maps.
_MTL_MAP_ROLES = {"map_kd": "base_color", "norm": "normal", "map_bump": "normal", "bump": "normal",
                  "map_ao": "occlusion", "map_ke": "emission"}
_GREY_MODES = ("1", "L", "LA", "I", "I;16", "F")


def _read_mtl_textures(obj_path: Path, libraries: list[Path]) -> tuple[dict[str, dict[str, Path]], set]:
    """(material name -> {role: the file its first map statement of that role
    names (which may not exist)}, for every material the libraries define;
    the materials whose colour map says -clamp on). Names are decoded as
    _native.read_obj decodes usemtl names, so that they match byte for byte."""
    from atlas_defrag import mtl_text

    textures: dict[str, dict[str, Path]] = {}
    clamped = set()
    for mtl in libraries:
        if not mtl.is_file():
            continue
        current = None
        for line in mtl.read_text(encoding="utf-8-sig", errors="surrogateescape").splitlines():
            parts = line.split(None, 1)
            if not parts:
                continue
            keyword, rest = parts[0].lower(), parts[1].strip() if len(parts) > 1 else ""
            if keyword == "newmtl":
                current = rest
                textures.setdefault(current, {})
            elif keyword in _MTL_MAP_ROLES and current is not None:
                if mtl_text.uv_transform(rest):
                    raise ValueError(f"{mtl.name}: material '{current}' reads its texture through "
                                     f"'{mtl_text.uv_transform(rest)}' (UVs moved or scaled), "
                                     "which this reader does not apply")
                if keyword == "map_kd" and "base_color" not in textures[current] and mtl_text.clamps(rest):
                    clamped.add(current)
                textures.setdefault(current, {}).setdefault(_MTL_MAP_ROLES[keyword],
                                                            _texture_path(rest, [mtl.parent, obj_path.parent]))
    return textures, clamped


def _other_maps(maps: dict[str, Path], material: str, warnings: list) -> dict[str, Path]:
    """The maps of a material besides its base colour that the job can carry
    over: each missing file, and a grey bump map (heights, not normals), is
    left out with a warning."""
    from PIL import Image

    out = {}
    for role, path in maps.items():
        if role == "base_color":
            continue
        if not path.is_file():
            warnings.append(f"{role} map {path} of material '{material}' not found: left out")
            continue
        if role == "normal":
            with Image.open(path) as img:
                if img.mode in _GREY_MODES:
                    warnings.append(f"bump map {path} of material '{material}' is grey, a height map rather "
                                    "than a normal map: left out")
                    continue
        out[role] = path
    return out


def load_obj(path: Path) -> Scan:
    """The geometry through the native reader (_native.read_obj): parsing in
    Python was the command-line entry's slowest stage on large scans
    (bench/README.md)."""
    from atlas_defrag import _native

    obj = _native.read_obj(str(path))
    tris, uv_idx = obj["triangles"], obj["texcoord_index"]
    has_uv = uv_idx[:, 0] >= 0
    vt = obj["texcoords"]
    uvs = vt[np.maximum(uv_idx, 0)] if len(vt) else np.zeros((len(tris), 3, 2))
    uvs[~has_uv] = 0.0

    libraries, missing = _material_libraries(path, obj["material_libraries"])
    textures, clamped = _read_mtl_textures(path, libraries)
    pages, page_of = [], {}
    warnings = [f"material library {m} not found beside {path.name}: the materials it defines are left untextured"
                for m in missing]
    if obj["vertex_colours"]:
        warnings.append(_VERTEX_COLOURS)
    material_page = np.full(len(obj["materials"]) + 1, -1, dtype=np.int32)  # the last: no usemtl
    used, first_face, counts = np.unique(obj["face_material"][has_uv], return_index=True, return_counts=True)
    for k in np.argsort(first_face):  # pages in the order faces first use them
        m = used[k]
        name = obj["materials"][m] if m >= 0 else ""
        maps = textures.get(name, {}) if m >= 0 else {}
        if m >= 0 and name not in textures and not missing:  # else the missing library was named
            warnings.append(f"material '{name}' is defined in no material library: its {counts[k]} faces "
                            "are left untextured")
        tex = maps.get("base_color")
        if tex is not None and not tex.is_file():
            warnings.append(f"texture {tex} of material '{name}' not found: its {counts[k]} "
                            "faces are left untextured")
        if tex is None or not tex.is_file():
            continue
        page = {"base_color": tex, **_other_maps(maps, name, warnings)}
        key = tuple(sorted((role, str(p)) for role, p in page.items()))
        if key not in page_of:
            page_of[key] = len(pages)
            pages.append(page)
        material_page[m] = page_of[key]
        if name in clamped:
            warnings += _clamp_warning(name, "clamps its colour texture (-clamp on)",
                                       uvs[has_uv & (obj["face_material"] == m)])
    face_page = np.where(has_uv, material_page[obj["face_material"]], -1).astype(np.int32)
    bases = [page["base_color"] for page in pages]
    sizes = np.array([_decodable_size(p, p.name) for p in bases], dtype=np.int32).reshape(-1, 2)
    normals, normal_index = _shading(obj["normals"] if len(obj["normals"]) else None, obj["normal_index"])
    return Scan(obj["positions"], tris, uvs, face_page, sizes, bases, pages,
                files=[path] + libraries + [p for page in pages for p in page.values()],
                warnings=warnings, normals=normals, normal_index=normal_index)


def _clamp_warning(material: str, how: str, corners: np.ndarray) -> list:
    """A warning when a colour map read clamped (or mirrored), as `how` says,
    has these corners' UVs leave its page: the bake repeats every image."""
    from atlas_defrag.job import reaches_past_page

    if not reaches_past_page(corners):
        return []
    return [f"material '{material}' {how} where faces reach past its edges: the new texture repeats it there"]


# ---- PLY ------------------------------------------------------------------

def load_ply(path: Path) -> Scan:
    """Texture k is the header's k-th TextureFile (faces with texnumber k);
    faces whose texture is missing, or without UVs, are left untextured."""
    from atlas_defrag import ply_io

    mesh = ply_io.read(path.read_bytes())
    found, face_page, missing = ply_io.face_textures(mesh, str(path.parent))
    pages = [Path(p) for p in found]
    face_page = face_page.astype(np.int32) if mesh.uvs is not None else np.full(len(mesh.triangles), -1, np.int32)
    uvs = mesh.uvs if mesh.uvs is not None else np.zeros((len(mesh.triangles), 3, 2))
    sizes = np.array([_decodable_size(p, p.name) for p in pages], dtype=np.int32).reshape(-1, 2)
    warnings = [f"texture {name} not found: its faces are left untextured" for name in missing] + mesh.notes
    if mesh.colours is not None:
        warnings.append(_VERTEX_COLOURS)
    triangles = mesh.triangles.astype(np.int32)
    normals, normal_index = _shading(mesh.normals, triangles if mesh.normals is not None else None)
    return Scan(mesh.positions, triangles, uvs, face_page, sizes, pages, [{"base_color": p} for p in pages],
                files=[path] + pages, warnings=warnings, normals=normals, normal_index=normal_index)


def _shading(normals, normal_index):
    """(normals, normal_index) with every face that names a normal that is
    no finite vector left without (-1, as the OBJ reader leaves it); both
    None when no face keeps one."""
    if normals is None:
        return None, None
    finite = np.isfinite(normals).all(axis=1)
    kept = (normal_index >= 0).all(axis=1) & finite[np.maximum(normal_index, 0)].all(axis=1)
    return (normals, np.where(kept[:, None], normal_index, -1).astype(np.int32)) if kept.any() else (None, None)


# ---- glTF and GLB -----------------------------------------------------------

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _item(items: list, index, what: str):
    """items[index] for a glTF index, which must be a non-negative int in range
    (Python would take -1 from the end)."""
    if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
        raise ValueError(f"{what} index {index!r} is out of range (0..{len(items) - 1})")
    return items[index]


def _view_values(gltf: dict, buffers: list, view_index: int, offset: int, count: int, dtype, width: int):
    """(count, width) values of dtype from a buffer view, byteStride honoured."""
    view = _item(gltf["bufferViews"], view_index, "bufferView")
    binary = _item(buffers, view["buffer"], "buffer")
    start = view.get("byteOffset", 0) + offset
    stride = view.get("byteStride", dtype.itemsize * width)
    length = stride * (count - 1) + dtype.itemsize * width
    if offset + length > view["byteLength"]:
        raise ValueError(f"an accessor reads {offset + length} bytes of bufferView {view_index}, "
                         f"which holds {view['byteLength']}")
    raw = np.frombuffer(binary, dtype=np.uint8, count=length, offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, (count, dtype.itemsize * width), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(count, width)


def _accessor(gltf: dict, buffers: list, index: int) -> np.ndarray:
    """An accessor's values: from its buffer view (zeros without one), with
    its sparse substitutions applied, normalized integers as floats."""
    acc = _item(gltf["accessors"], index, "accessor")
    dtype = np.dtype(_COMPONENTS[acc["componentType"]])
    width, count = _WIDTH[acc["type"]], acc["count"]
    if "bufferView" in acc:
        values = _view_values(gltf, buffers, acc["bufferView"], acc.get("byteOffset", 0), count, dtype, width)
    else:
        values = np.zeros((count, width), dtype)
    sparse = acc.get("sparse")
    if sparse:
        n = sparse["count"]
        at = sparse["indices"]
        rows = _view_values(gltf, buffers, at["bufferView"], at.get("byteOffset", 0), n,
                            np.dtype(_COMPONENTS[at["componentType"]]), 1)[:, 0].astype(np.int64)
        if n and (rows.min() < 0 or rows.max() >= count):
            raise ValueError(f"accessor {index}: a sparse index is out of range")
        values = values.copy()
        values[rows] = _view_values(gltf, buffers, sparse["values"]["bufferView"],
                                    sparse["values"].get("byteOffset", 0), n, dtype, width)
    if acc.get("normalized"):
        values = values.astype(np.float64) / np.iinfo(dtype).max
    return values


def _uri_bytes(uri: str, folder: Path) -> bytes:
    """A glTF uri: an embedded data: URI, or a file beside the .gltf."""
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    path = folder / urllib.parse.unquote(uri)
    if path.exists() and not path.is_file():  # a device would be read without end, a FIFO waited on
        raise ValueError(f"{path} is not a regular file")
    return path.read_bytes()


class UnreadableTexture(ValueError):
    """A texture whose images are all in formats this reader cannot decode."""


class Unsupported(ValueError):
    """A well-formed glTF using what this reader does not do: said as it is,
    not as a malformed file."""


def _texture_source(texture: dict) -> int:
    """The image of a texture: its own source (the PNG or JPEG fallback when
    there is one), else the WebP one of EXT_texture_webp, which Pillow reads.
    UnreadableTexture for images only in formats Pillow cannot read (KTX2)."""
    if "source" in texture:
        return texture["source"]
    extensions = texture.get("extensions", {})
    if "source" in extensions.get("EXT_texture_webp", {}):
        return extensions["EXT_texture_webp"]["source"]
    raise UnreadableTexture(f"a texture has no image this reader can decode ({', '.join(extensions) or 'no source'})")


def _image_bytes(gltf: dict, buffers: list, folder: Path, texture_index: int) -> bytes:
    texture = _item(gltf["textures"], texture_index, "texture")
    image = _item(gltf["images"], _texture_source(texture), "image")
    if "uri" in image:
        return _uri_bytes(image["uri"], folder)
    view = _item(gltf["bufferViews"], image["bufferView"], "bufferView")
    start = view.get("byteOffset", 0)
    binary = _item(buffers, view["buffer"], "buffer")
    if start + view["byteLength"] > len(binary):
        raise ValueError(f"image {_texture_source(texture)} lies in bytes {start}-{start + view['byteLength']} of "
                         f"buffer {view['buffer']}, which holds {len(binary)}")
    return binary[start:start + view["byteLength"]]


def _image_name(gltf: dict, texture_index: int) -> str:
    """A texture's image as a message names it: its file, else its index."""
    index = _texture_source(_item(gltf["textures"], texture_index, "texture"))
    uri = _item(gltf["images"], index, "image").get("uri", "data:")
    return f"image {index}" if uri.startswith("data:") else urllib.parse.unquote(uri)


def _decodable_size(data, name: str) -> tuple[int, int]:
    """image_size of a scan's image (its bytes or file), UnreadableTexture naming it when Pillow cannot read it."""
    from PIL import UnidentifiedImageError

    try:
        return image_size(data)
    except UnidentifiedImageError:
        raise UnreadableTexture(f"its {name} is in no image format this reader decodes") from None
    except OSError as exc:
        raise UnreadableTexture(f"its {name} cannot be decoded: {exc}") from None


def _node_matrices(gltf: dict):
    """World matrix of every node that holds a mesh."""
    def local(node):
        if "matrix" in node:
            return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        t = np.eye(4)
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        t[:3, :3] = r * np.asarray(node.get("scale", [1, 1, 1]))
        t[:3, 3] = node.get("translation", [0, 0, 0])
        return t

    nodes = gltf.get("nodes", [])
    children = {c for node in nodes for c in node.get("children", [])}
    roots = _item(gltf["scenes"], gltf.get("scene", 0), "scene").get("nodes", []) if gltf.get("scenes") \
        else [n for n in range(len(nodes)) if n not in children]
    # The nodes form a tree: a node reached twice (a cycle, or two parents
    # sharing it) would otherwise be walked forever or 2^depth times.
    stack, reached = [(n, np.eye(4)) for n in roots], set()
    while stack:
        n, parent = stack.pop()
        node = _item(nodes, n, "node")
        if n in reached:
            raise ValueError(f"glTF node {n} is reached twice (the node hierarchy must be a tree)")
        reached.add(n)
        world = parent @ local(node)
        if "mesh" in node:
            yield node["mesh"], world
        stack.extend((c, world) for c in node.get("children", []))


def load_glb(path: Path) -> Scan:
    data = path.read_bytes()
    if len(data) < 20 or struct.unpack_from("<I", data, 0)[0] != 0x46546C67:
        raise ValueError("not a binary glTF file")
    declared = struct.unpack_from("<I", data, 8)[0]
    if declared > len(data):
        raise ValueError(f"the file is cut short: its header gives {declared:,} bytes and it holds {len(data):,} "
                         "(an interrupted download or copy?)")
    json_len, _ = struct.unpack_from("<II", data, 12)
    gltf = _parsed_json(data[20:20 + json_len])
    bin_offset = 20 + json_len
    chunk = b""
    if bin_offset + 8 <= len(data):
        bin_len, _ = struct.unpack_from("<II", data, bin_offset)
        chunk = data[bin_offset + 8:bin_offset + 8 + bin_len]
    # Buffer 0 without a uri is the binary chunk; any other is a uri.
    return _checked_gltf(path, gltf, lambda: [chunk if "uri" not in b else _uri_bytes(b["uri"], path.parent)
                                              for b in gltf.get("buffers", [])])


def load_gltf(path: Path) -> Scan:
    """A .gltf file: JSON, with buffers and images in files beside it or in data: URIs."""
    gltf = _parsed_json(path.read_bytes())
    return _checked_gltf(path, gltf, lambda: [_uri_bytes(b["uri"], path.parent) for b in gltf.get("buffers", [])])


# Extensions that change what the accessors or UVs mean: read without them, a
# scan would come out wrong rather than fail.
_UNREAD_EXTENSIONS = {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_texture_transform"}
# Extensions a file may require that this reader reads (the glTF
# specification has a reader refuse a file requiring any other).
_READ_EXTENSIONS = {"KHR_materials_pbrSpecularGlossiness", "EXT_texture_webp", "KHR_mesh_quantization",
                    "KHR_materials_unlit"}


def _parsed_json(data: bytes):
    """The glTF's JSON; ValueError saying so for text that is not UTF-8 JSON (a
    file cut short, say) or that nests too deeply for Python's parser."""
    try:
        return json.loads(data.decode("utf-8-sig"))
    except RecursionError:
        raise ValueError("malformed glTF (its JSON nests too deeply)") from None
    except ValueError as exc:  # UnicodeDecodeError and JSONDecodeError
        raise ValueError(f"malformed glTF (its JSON part is not valid UTF-8 JSON: {exc})") from None


def _checked_gltf(path: Path, gltf, read_buffers) -> Scan:
    """The scan of a parsed glTF, or ValueError saying what is wrong with it:
    a glTF 1.0 file, a missing buffer or a malformed field would otherwise
    surface as a bare KeyError or TypeError, and a cycle of nodes as a hang."""
    asset = gltf.get("asset") if isinstance(gltf, dict) else None
    version = str(asset.get("version", "")) if isinstance(asset, dict) else ""
    if not version.startswith("2"):
        raise ValueError(f"not a glTF 2.0 file (asset version {version or 'missing'})")
    required, listed = (_names(gltf, "extensionsRequired"), _names(gltf, "extensionsUsed"))
    listed |= _extensions_in(gltf.get("materials", []))  # some writers leave extensionsUsed out
    unread = ((required | listed) & _UNREAD_EXTENSIONS) | (required - _READ_EXTENSIONS)
    if unread:
        raise ValueError(f"uses {', '.join(sorted(unread))}, which this reader does not support")
    try:
        scan = _scan_from_gltf(gltf, read_buffers(), path.parent)
        if scan is not None:
            scan.files = [path] + [path.parent / urllib.parse.unquote(item["uri"])
                                   for item in gltf.get("buffers", []) + gltf.get("images", [])
                                   if not item.get("uri", "data:").startswith("data:")]
    except (UnreadableTexture, Unsupported):
        raise
    except OSError as exc:
        raise ValueError(f"a file it refers to cannot be read: {exc}") from exc
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, struct.error) as exc:
        raise ValueError(f"malformed glTF ({type(exc).__name__}: {exc})") from exc
    if scan is None:
        raise ValueError("no triangle mesh in the file")
    if any(name.startswith("COLOR_") for mesh in gltf.get("meshes", []) for prim in mesh.get("primitives", [])
           for name in prim.get("attributes", {})):
        scan.warnings.append(_VERTEX_COLOURS)
    return scan


def _extensions_in(item) -> set:
    """The names of the extensions found anywhere inside item (parsed JSON)."""
    if isinstance(item, list):
        return set().union(*map(_extensions_in, item))
    if not isinstance(item, dict):
        return set()
    found = set(item["extensions"]) if isinstance(item.get("extensions"), dict) else set()
    return found.union(*map(_extensions_in, item.values()))


def _names(gltf: dict, key: str) -> set:
    """The strings a glTF lists under key (a list of extension names), or ValueError."""
    names = gltf.get(key, [])
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise ValueError(f"malformed glTF ({key} is not a list of names)")
    return set(names)


_TRIANGLES, _STRIP, _FAN = 4, 5, 6


def _primitive_triangles(gltf: dict, buffers: list, prim: dict, vertex_count: int) -> np.ndarray:
    """(T, 3) vertex indices of a triangle list, strip or fan; a primitive
    without indices lists its vertices in order. Strip triangles alternate
    their order so that all keep one winding; degenerate ones (a strip's
    joins) are dropped."""
    order = (_accessor(gltf, buffers, prim["indices"]).reshape(-1).astype(np.int64) if "indices" in prim
             else np.arange(vertex_count, dtype=np.int64))
    if order.size and (order.min() < 0 or order.max() >= vertex_count):
        raise ValueError(f"a vertex index is outside the primitive's {vertex_count} vertices")
    mode = prim.get("mode", _TRIANGLES)
    if mode == _TRIANGLES:
        return order[:len(order) - len(order) % 3].reshape(-1, 3)
    k = np.arange(max(len(order) - 2, 0))
    if mode == _STRIP:
        tris = np.stack([order[k + k % 2], order[k + 1 - k % 2], order[k + 2]], axis=1)
    else:
        tris = np.stack([np.full_like(k, order[0] if len(order) else 0), order[k + 1], order[k + 2]], axis=1)
    keep = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    return tris[keep]


def _colour_texture(material: dict):
    """The base colour texture slot of a glTF material, or None. Older exports
    (Sketchfab among them) give it as the diffuse texture of the
    specular-glossiness extension only."""
    return material.get("pbrMetallicRoughness", {}).get("baseColorTexture") or material.get(
        "extensions", {}).get("KHR_materials_pbrSpecularGlossiness", {}).get("diffuseTexture")


def _map_slots(material: dict) -> list:
    """(role, texture slot) of each map a textured material has, base colour first."""
    pbr = material.get("pbrMetallicRoughness", {})
    slots = [("base_color", _colour_texture(material)), ("normal", material.get("normalTexture")),
             ("occlusion", material.get("occlusionTexture")),
             ("metallic_roughness", pbr.get("metallicRoughnessTexture")), ("emission", material.get("emissiveTexture"))]
    return [(role, slot) for role, slot in slots if slot is not None]


def _material_maps(gltf: dict, buffers: list, folder: Path, material: dict, warnings: set) -> dict:
    """role -> image bytes of a textured material: base colour, then the
    normal, occlusion, metallic-roughness and emission maps it has. A map
    only in a format Pillow cannot read is left out: the colour still bakes.
    So is a map whose file is missing, with a warning, as the OBJ reader does."""
    (_, colour), *others = _map_slots(material)
    if any(slot.get("texCoord", 0) != colour.get("texCoord", 0) for _, slot in others):
        raise Unsupported("a material's maps read different TEXCOORD sets, which this reader does not support")
    roles = {"base_color": _image_bytes(gltf, buffers, folder, colour["index"])}
    for role, slot in others:
        try:
            roles[role] = _image_bytes(gltf, buffers, folder, slot["index"])
        except UnreadableTexture:
            pass
        except FileNotFoundError as exc:
            warnings.add(f"{role} map {exc.filename} of material '{material.get('name', '')}' not found: left out")
    return roles


def _page_key(gltf: dict, material: dict) -> tuple:
    """What tells a textured material's page: the image of each of its maps.
    Materials naming the same images share one page, as OBJ materials naming
    one file do (a texture whose image cannot be read counts by its index)."""
    key = []
    for role, slot in _map_slots(material):
        texture = _item(gltf["textures"], slot["index"], "texture")
        try:
            key.append((role, _texture_source(texture)))
        except UnreadableTexture:
            key.append((role, ("texture", slot["index"])))
    return tuple(key)


def _scan_from_gltf(gltf: dict, buffers: list, folder: Path):
    """The scan, or None when no node holds a triangle primitive."""
    positions, tris, uvs, face_page, normals, normal_index = [], [], [], [], [], []
    page_of, maps, names, sources, warnings = {}, [], [], [], set()
    first_corners = {}  # mesh index -> (corners of its first instance, whether that one mirrors)
    base = faces = 0
    for mesh_index, world in _node_matrices(gltf):
        mirrors = np.linalg.det(world[:3, :3]) < 0
        start = faces
        for prim in _item(gltf["meshes"], mesh_index, "mesh")["primitives"]:
            if prim.get("mode", _TRIANGLES) not in (_TRIANGLES, _STRIP, _FAN):
                continue  # points and lines
            pos = _accessor(gltf, buffers, prim["attributes"]["POSITION"]).astype(np.float64)
            pos = pos @ world[:3, :3].T + world[:3, 3]
            idx = _primitive_triangles(gltf, buffers, prim, len(pos))
            if mirrors:  # a mirroring transform turns the winding round
                idx = idx[:, ::-1]
            material = _item(gltf["materials"], prim["material"], "material") if "material" in prim else {}
            slot = _colour_texture(material) or {}
            coords = f"TEXCOORD_{slot.get('texCoord', 0)}"
            page = -1
            if coords in prim["attributes"]:
                uv = _accessor(gltf, buffers, prim["attributes"][coords]).astype(np.float64)
                uv[:, 1] = 1.0 - uv[:, 1]  # glTF puts v = 0 at the top
                uvs.append(uv[idx])
                if _colour_texture(material) is not None:
                    warnings |= _clamped_past_edges(gltf, material, uv[idx])
                    key = _page_key(gltf, material)
                    if key not in page_of:
                        page_of[key] = len(maps)
                        maps.append(_material_maps(gltf, buffers, folder, material, warnings))
                        names.append(_image_name(gltf, _colour_texture(material)["index"]))
                    page = page_of[key]
            else:
                uvs.append(np.zeros((len(idx), 3, 2)))
            shading = _world_normals(gltf, buffers, prim, world, len(pos))
            normals.append(shading if shading is not None else np.zeros((len(pos), 3)))
            normal_index.append(idx + base if shading is not None else np.full(idx.shape, -1))
            positions.append(pos)
            tris.append(idx + base)
            face_page.append(np.full(len(idx), page, dtype=np.int32))
            base += len(pos)
            faces += len(idx)
        sources.append(_instance_corners(first_corners, mesh_index, start, faces, mirrors))
    if not tris:
        return None
    pages = [m["base_color"] for m in maps]
    sizes = np.array([_decodable_size(p, name) for p, name in zip(pages, names)], dtype=np.int32).reshape(-1, 2)
    shading = _shading(np.concatenate(normals), np.concatenate(normal_index))
    return Scan(np.concatenate(positions), np.concatenate(tris).astype(np.int32), np.concatenate(uvs),
                np.concatenate(face_page), sizes, pages, maps, corner_source=np.concatenate(sources),
                warnings=sorted(warnings), normals=shading[0], normal_index=shading[1])


def _world_normals(gltf: dict, buffers: list, prim: dict, world: np.ndarray, count: int):
    """The primitive's NORMALs (count, 3: one per POSITION) in the scene's
    frame, turned by the inverse transpose of the node's matrix and made
    unit again; None when it has none."""
    if "NORMAL" not in prim["attributes"] or np.linalg.det(world[:3, :3]) == 0:
        return None  # a node scaled flat has no normals to turn
    normals = _accessor(gltf, buffers, prim["attributes"]["NORMAL"]).astype(np.float64)
    if len(normals) != count:
        raise ValueError(f"a primitive has {len(normals)} NORMALs for {count} POSITIONs (glTF asks as many)")
    turned = normals @ np.linalg.inv(world[:3, :3])  # (M^-T n)^T = n^T M^-1
    length = np.linalg.norm(turned, axis=1, keepdims=True)
    return np.divide(turned, length, out=np.zeros_like(turned), where=length > 0)


_REPEAT = 10497


def _clamped_past_edges(gltf: dict, material: dict, corners: np.ndarray) -> set:
    """A warning when the colour texture's sampler clamps or mirrors it where
    these corners' UVs leave the page: the bake repeats every image."""
    texture = _item(gltf["textures"], _colour_texture(material)["index"], "texture")
    sampler = _item(gltf.get("samplers", []), texture["sampler"], "sampler") if "sampler" in texture else {}
    wraps = (sampler.get("wrapS", _REPEAT), sampler.get("wrapT", _REPEAT))
    if wraps == (_REPEAT, _REPEAT):
        return set()
    return set(_clamp_warning(material.get("name", ""), "clamps or mirrors its colour texture (sampler wrap)",
                              corners))


def _instance_corners(first_corners: dict, mesh_index: int, start: int, end: int, mirrors: bool) -> np.ndarray:
    """Scan.corner_source of the faces start..end, one node's instance of a
    mesh: their own corners at the mesh's first instance, else the first's,
    in reverse order where one of the two mirrors and the other does not."""
    own = np.arange(3 * start, 3 * end, dtype=np.int64).reshape(-1, 3)
    if mesh_index not in first_corners:
        first_corners[mesh_index] = (own, mirrors)
        return own
    corners, first_mirrors = first_corners[mesh_index]
    return corners[:, ::-1] if mirrors != first_mirrors else corners
