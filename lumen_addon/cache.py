"""The cache on disk: a folder with `manifest.json` and one `.npz` of arrays (no pickle).

Writing is atomic at the manifest: arrays go to a content-named file first, then the manifest is
replaced in one rename, then files no manifest names are removed. A crash or a full disk leaves
the previous cache readable. Reading trusts nothing in the folder: sizes are checked against the
files and the reader's limits before anything big is read, only regular files are opened, every
manifest value is checked (type, range, consistency), arrays are read without pickle after their
zip and .npy headers were checked, images after their headers and specs were; every failure is a
CacheError that names the file. The format and the limits are in docs/cache-format.md.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import stat
import struct
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from . import __version__
from .atlas import LAYERS, PADDING, Atlas, split_atlas
from .bake import NO_CARDS, BakeSettings, Instance, SceneBake
from .sdf import (BAND_VOXELS, BRICK, BRICK_CELLS, HARD_MAX_RESOLUTION, INVALID_INSIDE, INVALID_OUTSIDE,
                  MARGIN_VOXELS, MIP_COUNT, MeshSDF, SDFMip)

FORMAT = "lumen-gi-cache"
VERSION = 2
MANIFEST = "manifest.json"
LOCK = ".lumen-lock"
MAX_MANIFEST_BYTES = 64 << 20


def _umask() -> int:
    """The process umask, read without changing it where the OS says it (os.umask(0) and back
    would leave a window in which another thread creates files world-writable)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


class CacheError(Exception):
    """A cache could not be written or read; the message names the file."""


SCENE_TOKEN = "{scene}"     # in a cache folder setting: the scene's name, as folder_name() spells it
_WINDOWS_DEVICES = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)),
                    *(f"LPT{i}" for i in range(10))}


def folder_name(name: str) -> str:
    """`name` (a scene's) as one folder name that means the same on every system: ASCII letters,
    digits, '.', '-' and '_' are kept, anything else becomes '_'. A name that had to change, or
    that a file system would read otherwise (empty, starting or ending with '.', a Windows device
    name such as CON, which also gets a leading '_'), gets '-' and 8 hex digits of its SHA-1, so
    two scenes never share one folder."""
    def device(n):
        return n.split(".")[0].upper() in _WINDOWS_DEVICES

    safe = re.sub(r"[^A-Za-z0-9._-]", "_", name)[:64]
    if safe != name or not safe or safe.startswith(".") or safe.endswith(".") or device(safe):
        safe = safe.strip(".")
        digest = hashlib.sha1(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
        safe = f"{'_' if device(safe) else ''}{safe}-{digest}"
    return safe


def write_cache(folder, bake: SceneBake) -> Path:
    """Write `bake` into `folder` (created if needed) atomically; returns the manifest path."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CacheError(f"cannot create cache folder {folder}: {exc.strerror or exc}") from exc
    if not os.access(folder, os.W_OK):
        raise CacheError(f"cache folder {folder} is not writable")
    _own_files(folder)                     # refuse another tool's folder before writing anything
    with _folder_lock(folder):
        return _write_locked(folder, bake)


def _write_locked(folder: Path, bake: SceneBake) -> Path:
    previous = _own_files(folder)          # again under the lock: another writer may have been first

    arrays, meshes = {}, []
    for i, (key, sdf) in enumerate(bake.meshes.items()):
        mips = []
        for k, mip in enumerate(sdf.mips):
            ind, bri = f"mesh{i}_mip{k}_indirection", f"mesh{i}_mip{k}_bricks"
            arrays[ind], arrays[bri] = mip.indirection.astype(np.int32), mip.bricks.astype(np.uint8)
            mips.append({"voxel_size": mip.voxel_size, "resolution": list(mip.resolution),
                         "brick_grid": list(mip.brick_grid), "bricks_kept": int(len(mip.bricks)),
                         "band": mip.band, "indirection": ind, "bricks": bri})
        meshes.append({"hash": key, "objects": [x.name for x in bake.instances if x.mesh == key],
                       "origin": sdf.origin.tolist(), "bounds_min": sdf.bounds_min.tolist(),
                       "bounds_max": sdf.bounds_max.tolist(), "two_sided": sdf.two_sided,
                       "requested_resolution": list(sdf.requested_resolution), "mips": mips,
                       "edge_voxels": [None if x is None else float(x) for x in sdf.edge_voxels],
                       "stats": sdf.stats()})
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    payload = buf.getvalue()
    digest = hashlib.sha256(payload).hexdigest()
    npz_name = f"sdf-{digest[:16]}.npz"
    manifest = {
        "format": FORMAT, "version": VERSION, "generator": f"lumen_gi {__version__}",
        "units": "metres", "axes": "arrays are indexed [x, y, z]",
        "settings": {"voxel_density": bake.settings.voxel_density,
                     "max_resolution": bake.settings.max_resolution,
                     "inside_fraction": bake.settings.inside_fraction,
                     "texel_density": bake.settings.texel_density,
                     "texel_budget": bake.settings.texel_budget,
                     "max_cards": bake.settings.max_cards,
                     "min_card_size": bake.settings.min_card_size},
        "sdf": {"brick_size": BRICK, "brick_cells": BRICK_CELLS, "band_voxels": BAND_VOXELS,
                "encoding": ENCODING, "invalid_outside": INVALID_OUTSIDE, "invalid_inside": INVALID_INSIDE,
                "file": npz_name, "sha256": digest, "size": len(payload)},
        "meshes": meshes,
        "instances": [{"object": x.name, "mesh": x.mesh, "cards": x.cards,
                       "matrix_world": np.asarray(x.matrix_world).tolist()} for x in bake.instances],
        "stats": bake.stats(),
    }
    try:
        _atomic_write(folder / npz_name, payload)
        keep = {npz_name}
        if bake.atlas is not None and bake.atlas.table:
            manifest["atlas"] = _write_atlas(folder, bake)
            keep |= {e["file"] for e in manifest["atlas"]["layers"].values()}
        _atomic_write(folder / MANIFEST, json.dumps(manifest, indent=1).encode())
    except OSError as exc:
        raise CacheError(f"cannot write cache in {folder}: {exc.strerror or exc}") from exc
    for name in previous - keep:            # only files our previous manifest named
        try:
            (folder / name).unlink()
        except OSError:
            pass   # an old file left behind is harmless: no manifest names it
    return folder / MANIFEST


def _own_files(folder: Path) -> set:
    """The data files the folder's current manifest names, if Lumen GI wrote it (empty without a
    manifest). A manifest.json of another tool (not JSON, or another "format") is a CacheError:
    we never overwrite it, nor delete any file that our own manifest did not name."""
    path = folder / MANIFEST
    if not path.exists():
        return set()
    try:
        if not path.is_file() or path.stat().st_size > MAX_MANIFEST_BYTES:
            raise ValueError("not a manifest of ours")
        old = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(old, dict) or old.get("format") != FORMAT:
            raise ValueError("another format")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise CacheError(f"{path} was not written by Lumen GI ({exc}); choose an empty folder or "
                         f"one of Lumen GI's caches") from exc
    names = set()
    sdf = old.get("sdf")
    if isinstance(sdf, dict) and isinstance(sdf.get("file"), str):
        names.add(sdf["file"])
    layers = (old.get("atlas") or {}).get("layers") if isinstance(old.get("atlas"), dict) else None
    for entry in (layers or {}).values() if isinstance(layers, dict) else ():
        if isinstance(entry, dict) and isinstance(entry.get("file"), str):
            names.add(entry["file"])
    # only plain names of our own patterns: a crafted manifest cannot point the clean-up elsewhere
    return {n for n in names if n == Path(n).name and (n.startswith("sdf-") and n.endswith(".npz")
                                                        or n.startswith("atlas-"))}


class _folder_lock:
    """An exclusive lock on <folder>/.lumen-lock for one writer at a time (POSIX flock; where
    that is unavailable, no lock: one writer per folder is then the user's to keep)."""

    def __init__(self, folder: Path):
        self.path = folder / LOCK
        self.fh = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:
            return self
        try:
            self.fh = open(self.path, "a+b")
            fcntl.flock(self.fh.fileno(), fcntl.LOCK_EX)
        except OSError as exc:
            if self.fh:
                self.fh.close()
            raise CacheError(f"cannot lock cache folder {self.path.parent}: "
                             f"{exc.strerror or exc}") from exc
        return self

    def __exit__(self, *exc):
        if self.fh is not None:
            import fcntl
            fcntl.flock(self.fh.fileno(), fcntl.LOCK_UN)
            self.fh.close()
        return False


def _write_atlas(folder: Path, bake: SceneBake) -> dict:
    """Each layer as a float EXR, albedo also as an sRGB PNG; content-named, atomically."""
    atlas = bake.atlas
    layers = {}
    srgb = np.where(atlas.layers["albedo"] <= 0.0031308, atlas.layers["albedo"] * 12.92,
                    1.055 * np.power(np.clip(atlas.layers["albedo"], 0.0031308, None), 1 / 2.4) - 0.055)
    images = [(name, "exr", atlas.layers[name]) for name in LAYERS]
    images.append(("albedo_srgb", "png", np.clip(np.rint(srgb * 255), 0, 255).astype(np.uint8)))
    for name, ext, data in images:
        digest, size = _write_image(folder, name.replace("_", "-"), ext, data)
        layers[name] = {"file": f"atlas-{name.replace('_', '-')}-{digest[:16]}.{ext}", "sha256": digest,
                        "size": size, "channels": int(data.shape[2]),
                        "type": "uint8 sRGB" if ext == "png" else "float32 linear"}
    return {"size": list(atlas.size), "padding": PADDING, "layers": layers,
            "cards": atlas.table,
            "coverage": {key: mc.coverage for key, mc in bake.cards.items()},
            "texel_origin": "card texel (i, j) = atlas pixel [rect.y + j, rect.x + i]; row 0 is "
                            "the first scanline of the files; u along x, v along y"}


def _write_image(folder: Path, stem: str, ext: str, data: np.ndarray):
    """Encode with OpenImageIO (into a scratch file: it writes files), then write atomically
    under a content name. Returns (sha256, size)."""
    import OpenImageIO as oiio

    fd, scratch = tempfile.mkstemp(prefix=f".atlas-{stem}.", suffix=f".{ext}", dir=folder)
    os.close(fd)
    try:
        fmt = oiio.UINT8 if data.dtype == np.uint8 else oiio.FLOAT
        spec = oiio.ImageSpec(int(data.shape[1]), int(data.shape[0]), int(data.shape[2]), fmt)
        if ext == "exr":
            spec.attribute("compression", "zip")
        out = oiio.ImageOutput.create(scratch)
        if out is None or not out.open(scratch, spec) or not out.write_image(np.ascontiguousarray(data)):
            raise OSError(f"OpenImageIO could not write {scratch}: {oiio.geterror()}")
        out.close()
        payload = Path(scratch).read_bytes()
    finally:
        Path(scratch).unlink(missing_ok=True)
    digest = hashlib.sha256(payload).hexdigest()
    _atomic_write(folder / f"atlas-{stem}-{digest[:16]}.{ext}", payload)
    return digest, len(payload)


def _atomic_write(path: Path, data: bytes):
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())    # as open() would: teammates can read an export
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# -- reading ------------------------------------------------------------------------------------
# A cache can come from anywhere (a download, a teammate's export, a crafted folder), so the
# reader trusts nothing in it: every size is checked against the file and against the limits
# below before anything big is read, only regular files inside the folder are opened (never a
# symlink, FIFO, device or directory), every manifest value is checked for type, range and
# consistency, and every failure is a CacheError whose message starts with the file it is about.
# The limits are documented in docs/cache-format.md ("Limits of the reader").

MAX_SDF_BYTES = 4 << 30          # the .npz: every SDF array of the scene (stored, not compressed)
MAX_ATLAS_SIDE = 1 << 15         # texels along one side of the atlas
MAX_ATLAS_TEXELS = 1 << 26       # texels of the atlas (8192 x 8192)
MAX_ENTRIES = 1 << 20            # meshes, instances, cards or coverage entries
MAX_NAME = 1024                  # characters of an object name
MAX_TEXT = 4096                  # characters of a descriptive string (generator, axes, ...)
MAX_COORD = 1e12                 # metres: any position, extent, depth or matrix entry
MAX_DENSITY = 1e12               # voxels or texels per metre (any finite request: max_resolution clamps it)
MIN_VOXEL = 1e-12                # metres
MAX_MIP_RESOLUTION = HARD_MAX_RESOLUTION + BRICK_CELLS   # voxels per axis of any mip
MAX_CARD_INDEX = 1 << 16
MAX_SECONDS = 1e9
MAX_NPY_HEADER = 1024            # bytes of one .npy header (numpy writes about 128)
ZIP_OVERHEAD = 2048              # bytes of zip and .npy framing per array, at most
IMAGE_OVERHEAD = 1 << 20         # bytes of an image file beyond its pixels (headers, offsets)
MAX_INT_DIGITS = 20              # JSON integers: |n| < 10**20
ENCODING = "uint8 code c -> distance (c - 127.5) / 127.5 * band"
LAYER_TYPES = {"exr": "float32 linear", "png": "uint8 sRGB"}
INTERNAL = "internal error"      # in a CacheError: a failure none of the checks foresaw (a bug)
_CHUNK = 1 << 20
_HEX_KEY = re.compile(r"[0-9a-f]{1,64}")
_SHA256 = re.compile(r"[0-9a-f]{64}")


def read_cache(folder) -> SceneBake:
    """Read and validate a cache folder (or its manifest.json path).

    Returns the bake, or raises CacheError naming the file: for a missing, truncated, modified,
    oversized or inconsistent cache, a value out of range, a file that is not a regular file
    inside the folder, and (marked "internal error") anything no check foresaw."""
    mpath = Path(str(folder))
    try:
        mpath = mpath if mpath.name == MANIFEST else mpath / MANIFEST
        return _decode(_load_manifest(mpath), mpath)
    except CacheError:
        raise
    except Exception as exc:        # MemoryError, RecursionError, a library's own error...
        raise CacheError(f"{mpath}: {INTERNAL} while reading the cache "
                         f"({type(exc).__name__}: {_short(exc)})") from exc


def _short(value, n: int = 80) -> str:
    """repr of a (hostile) value for a message, at most about n characters."""
    text = repr(value) if not isinstance(value, BaseException) else str(value)
    return text if len(text) <= n else text[:n] + "..."


def _kind(value) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "a list", dict: "an object", type(None): "null"}.get(type(value), type(value).__name__)


def _regular(path: Path, what: str = "file") -> os.stat_result:
    """lstat of a file the cache names: it must exist and be a regular file (not a symlink,
    FIFO, device, socket or directory), checked before it is opened."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        raise CacheError(f"{path}: missing ({what} named by the cache)") from None
    except (OSError, ValueError) as exc:
        raise CacheError(f"{path}: cannot stat ({getattr(exc, 'strerror', None) or exc})") from exc
    if not stat.S_ISREG(st.st_mode):
        kind = ("a symbolic link" if stat.S_ISLNK(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode)
                else "a directory" if stat.S_ISDIR(st.st_mode) else "a device or socket")
        raise CacheError(f"{path}: is {kind}, not a regular file; a cache holds regular files only")
    return st


def _open_regular(path: Path, size: int):
    """Open a file already checked by _regular, refusing it if it changed into something else
    meanwhile (no following links, no blocking on a FIFO) or its size is not `size`."""
    flags = (os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
             | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0))
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise CacheError(f"{path}: cannot open ({exc.strerror or exc})") from exc
    fh = os.fdopen(fd, "rb")
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_size != size:
        fh.close()
        raise CacheError(f"{path}: changed while it was read (now {st.st_size} bytes, not {size})")
    return fh


class _Refused(ValueError):
    pass


def _json_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _Refused(f"number {_short(text, 40)} is not finite")
    return value


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) >= MAX_INT_DIGITS:
        raise _Refused(f"integer {_short(text, 40)} has more than {MAX_INT_DIGITS - 1} digits")
    return int(text)


def _json_constant(text: str):
    raise _Refused(f"{text} is not a number a cache may hold")


def _load_manifest(mpath: Path) -> dict:
    """The manifest as JSON, its size checked before reading; NaN, infinities and integers of
    20 or more digits are refused while parsing."""
    try:
        st = _regular(mpath, "manifest")
    except CacheError as exc:
        if not mpath.parent.is_dir() or not os.path.lexists(mpath):
            raise CacheError(f"{mpath}: no cache manifest here") from exc
        raise
    if st.st_size > MAX_MANIFEST_BYTES:
        raise CacheError(f"{mpath}: {st.st_size} bytes, more than the {MAX_MANIFEST_BYTES} a "
                         f"cache manifest may have")
    with _open_regular(mpath, st.st_size) as fh:
        raw = fh.read(st.st_size + 1)
    try:
        manifest = json.loads(raw.decode("utf-8"), parse_float=_json_float, parse_int=_json_int,
                              parse_constant=_json_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CacheError(f"{mpath}: not a Lumen GI cache manifest ({_short(exc)})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise CacheError(f"{mpath}: not a Lumen GI cache manifest")
    version = manifest.get("version")
    if type(version) is not int or version != VERSION:
        raise CacheError(f"{mpath}: cache version {_short(version, 40)}, this build reads version "
                         f"{VERSION}; bake again")
    return manifest


class _Values:
    """Typed, range-checked reads of manifest values; a failure names the manifest and the key."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, where: str, what: str):
        raise CacheError(f"{self.path}: {where} {what}")

    def dict(self, value, where: str, keys=()) -> dict:
        if type(value) is not dict:
            self.fail(where, f"must be an object, is {_kind(value)}")
        for key in keys:
            if key not in value:
                self.fail(where, f"has no {key!r}")
        return value

    def list(self, value, where: str, lo: int = 0, hi: int = MAX_ENTRIES) -> list:
        if type(value) is not list:
            self.fail(where, f"must be a list, is {_kind(value)}")
        if not lo <= len(value) <= hi:
            self.fail(where, f"must have {lo if lo == hi else f'{lo}..{hi}'} entries, has {len(value)}")
        return value

    def int(self, value, where: str, lo: int, hi: int) -> int:
        if type(value) is not int:
            self.fail(where, f"must be an integer, is {_kind(value)} {_short(value, 40)}")
        if not lo <= value <= hi:
            self.fail(where, f"must be within {lo}..{hi}, the manifest says {value}")
        return value

    def num(self, value, where: str, lo: float = -MAX_COORD, hi: float = MAX_COORD) -> float:
        if type(value) not in (int, float):
            self.fail(where, f"must be a number, is {_kind(value)} {_short(value, 40)}")
        if not (math.isfinite(value) and lo <= value <= hi):
            self.fail(where, f"must be a finite number within {lo:g}..{hi:g}, the manifest says "
                             f"{value!r}")
        return float(value)

    def bool(self, value, where: str) -> bool:
        if type(value) is not bool:
            self.fail(where, f"must be true or false, is {_kind(value)} {_short(value, 40)}")
        return value

    def str(self, value, where: str, hi: int = MAX_NAME, lo: int = 0) -> str:
        if type(value) is not str:
            self.fail(where, f"must be a string, is {_kind(value)} {_short(value, 40)}")
        if not lo <= len(value) <= hi:
            self.fail(where, f"must have {lo}..{hi} characters, has {len(value)}")
        return value

    def key(self, value, where: str) -> str:
        """A content hash naming a mesh or its cards: 1..64 lowercase hex digits."""
        if type(value) is not str or not _HEX_KEY.fullmatch(value):
            self.fail(where, f"must be a hash of 1..64 hex digits, is {_short(value, 40)}")
        return value

    def equal(self, value, where: str, want):
        if type(value) is not type(want) or value != want:
            self.fail(where, f"must be {want!r}, is {_short(value, 40)}")

    def vec(self, value, where: str, n: int, lo: float = -MAX_COORD, hi: float = MAX_COORD):
        self.list(value, where, n, n)
        return np.array([self.num(x, f"{where}[{j}]", lo, hi) for j, x in enumerate(value)])

    def ints(self, value, where: str, n: int, lo: int, hi: int) -> tuple:
        self.list(value, where, n, n)
        return tuple(self.int(x, f"{where}[{j}]", lo, hi) for j, x in enumerate(value))


def _file_entry(v: _Values, entry, where: str, stem: str, ext: str, cap: int):
    """(path, sha256, size) of a file the manifest names. Its name must be the one the writer
    gives it (`<stem>-<first 16 hex of its SHA-256>.<ext>`: a plain name inside the folder)."""
    v.dict(entry, where, ("file", "sha256", "size"))
    sha = entry["sha256"]
    if type(sha) is not str or not _SHA256.fullmatch(sha):
        v.fail(f"{where}.sha256", f"must be 64 lowercase hex digits, is {_short(sha, 80)}")
    size = v.int(entry["size"], f"{where}.size", 1, cap)
    name = v.str(entry["file"], f"{where}.file", 200)
    if name != f"{stem}-{sha[:16]}.{ext}":
        v.fail(f"{where}.file", f"must be {stem}-{sha[:16]}.{ext} (a plain name carrying the start "
                                f"of its SHA-256), is {_short(name, 80)}")
    return v.path.parent / name, sha, size


def _settings(v: _Values, s) -> BakeSettings:
    v.dict(s, "settings", ("voxel_density", "max_resolution", "inside_fraction", "texel_density",
                           "texel_budget", "max_cards"))
    return BakeSettings(
        v.num(s["voxel_density"], "settings.voxel_density", MIN_VOXEL, MAX_DENSITY),
        v.int(s["max_resolution"], "settings.max_resolution", 2 * MARGIN_VOXELS + BRICK_CELLS,
              HARD_MAX_RESOLUTION),
        v.num(s["inside_fraction"], "settings.inside_fraction", 0.0, 1.0),
        v.num(s["texel_density"], "settings.texel_density", MIN_VOXEL, MAX_DENSITY),
        v.int(s["texel_budget"], "settings.texel_budget", 1, 2 ** 31 - 1),
        v.int(s["max_cards"], "settings.max_cards", 1, MAX_CARD_INDEX),
        # optional: caches from before it gave every object its cards
        v.num(s.get("min_card_size", 0.0), "settings.min_card_size", 0.0, MAX_COORD))


def _mesh(v: _Values, m, i: int):
    """(hash, MeshSDF without arrays, [(array name, dtype, shape)] of its mips) of meshes[i]."""
    where = f"meshes[{i}]"
    v.dict(m, where, ("hash", "objects", "origin", "bounds_min", "bounds_max", "two_sided",
                      "requested_resolution", "mips", "stats", "edge_voxels"))
    key = v.key(m["hash"], f"{where}.hash")
    v.list(m["objects"], f"{where}.objects", 1)
    origin = v.vec(m["origin"], f"{where}.origin", 3)
    bmin = v.vec(m["bounds_min"], f"{where}.bounds_min", 3)
    bmax = v.vec(m["bounds_max"], f"{where}.bounds_max", 3)
    two_sided = v.bool(m["two_sided"], f"{where}.two_sided")
    requested = v.ints(m["requested_resolution"], f"{where}.requested_resolution", 3, 1, 10 ** 16)
    v.list(m["mips"], f"{where}.mips", MIP_COUNT, MIP_COUNT)
    mips, arrays, prev = [], [], None
    for k, mip in enumerate(m["mips"]):
        w = f"{where}.mips[{k}]"
        v.dict(mip, w, ("voxel_size", "resolution", "brick_grid", "bricks_kept", "band",
                        "indirection", "bricks"))
        h = v.num(mip["voxel_size"], f"{w}.voxel_size", MIN_VOXEL, MAX_COORD)
        if k and not math.isclose(h, mips[0].voxel_size * 2 ** k, rel_tol=1e-9):
            v.fail(f"{w}.voxel_size", f"must be 2^{k} times mip 0's ({mips[0].voxel_size!r}), is {h!r}")
        res = v.ints(mip["resolution"], f"{w}.resolution", 3, BRICK_CELLS, MAX_MIP_RESOLUTION)
        if any(r % BRICK_CELLS for r in res):
            v.fail(f"{w}.resolution", f"must be whole bricks (multiples of {BRICK_CELLS}), is {list(res)}")
        if prev is not None:   # each mip halves the previous one's voxels, rounded up to whole bricks
            want = tuple(-(-(r // 2 + r % 2) // BRICK_CELLS) * BRICK_CELLS for r in prev)
            if res != want:
                v.fail(f"{w}.resolution", f"must be {list(want)} (half of mip {k - 1}'s, in whole "
                                         f"bricks), is {list(res)}")
        grid = v.ints(mip["brick_grid"], f"{w}.brick_grid", 3, 1, MAX_MIP_RESOLUTION // BRICK_CELLS)
        if tuple(n * BRICK_CELLS for n in grid) != res:
            v.fail(f"{w}.brick_grid", f"{list(grid)} does not match resolution {list(res)}")
        kept = v.int(mip["bricks_kept"], f"{w}.bricks_kept", 0, int(np.prod(grid)))
        band = v.num(mip["band"], f"{w}.band", MIN_VOXEL, MAX_COORD)
        if not math.isclose(band, BAND_VOXELS * h, rel_tol=1e-9):
            v.fail(f"{w}.band", f"must be {BAND_VOXELS:g} voxels ({BAND_VOXELS * h!r}), is {band!r}")
        names = (f"mesh{i}_mip{k}_indirection", f"mesh{i}_mip{k}_bricks")
        for field_, name in zip(("indirection", "bricks"), names):
            if mip[field_] != name:
                v.fail(f"{w}.{field_}", f"must be {name!r}, is {_short(mip[field_], 60)}")
        arrays += [(names[0], np.dtype("<i4"), grid), (names[1], np.dtype("|u1"), (kept,) + (BRICK,) * 3)]
        mips.append(SDFMip(h, res, None, None))
        prev = res
    # The volume of mip 0 holds the mesh bounds (the bake centres them with a margin).
    top = origin + np.array(mips[0].resolution) * mips[0].voxel_size
    tol = 1e-6 * (float(np.abs(origin).max()) + float(np.abs(top).max())) + mips[0].voxel_size * 1e-3
    if (bmin > bmax).any() or (bmin < origin - tol).any() or (bmax > top + tol).any():
        v.fail(where, f"bounds {bmin.tolist()}..{bmax.tolist()} are not inside its SDF volume "
                      f"{origin.tolist()}..{top.tolist()}")
    # per mip: the field's rounding of convex edges (sdf.edge_rounding), null where unmeasured
    v.list(m["edge_voxels"], f"{where}.edge_voxels", MIP_COUNT, MIP_COUNT)
    edge = [None if x is None else v.num(x, f"{where}.edge_voxels[{j}]", 0.0, 1.0)
            for j, x in enumerate(m["edge_voxels"])]
    sdf = MeshSDF(origin=origin, bounds_min=bmin, bounds_max=bmax, two_sided=two_sided, mips=mips,
                  requested_resolution=requested, edge_voxels=edge)
    return key, sdf, arrays


def _instances(v: _Values, entries, meshes: dict) -> list:
    v.list(entries, "instances", 1)
    out, mats = [], np.empty((len(entries), 4, 4))
    for n, x in enumerate(entries):
        where = f"instances[{n}]"
        v.dict(x, where, ("object", "mesh", "cards", "matrix_world"))
        name = v.str(x["object"], f"{where}.object", MAX_NAME, 1)
        if v.key(x["mesh"], f"{where}.mesh") not in meshes:
            v.fail(f"{where}.mesh", f"names no mesh of this cache (instance {name!r})")
        cards = v.key(x["cards"], f"{where}.cards")
        rows = v.list(x["matrix_world"], f"{where}.matrix_world", 4, 4)
        for r, row in enumerate(rows):
            v.list(row, f"{where}.matrix_world[{r}]", 4, 4)
            if not all(type(e) in (int, float) for e in row):
                v.fail(f"{where}.matrix_world[{r}]", "must hold numbers only")
        mats[n] = rows
        out.append(Instance(name, x["mesh"], mats[n], cards))
    bad = ~(np.abs(mats) <= MAX_COORD).all(axis=(1, 2)) | (mats[:, 3] != (0.0, 0.0, 0.0, 1.0)).any(axis=1)
    if bad.any():
        n = int(np.flatnonzero(bad)[0])
        v.fail(f"instances[{n}].matrix_world", f"must be an affine 4x4 matrix (last row 0 0 0 1) "
                                               f"with entries within +-{MAX_COORD:g}")
    return out


def _atlas_info(v: _Values, a):
    """(width, height, {layer: (path, sha, size)}, card table, coverage) of manifest["atlas"]."""
    v.dict(a, "atlas", ("size", "padding", "layers", "cards", "coverage", "texel_origin"))
    width, height = v.ints(a["size"], "atlas.size", 2, 1, MAX_ATLAS_SIDE)
    if width * height > MAX_ATLAS_TEXELS:
        v.fail("atlas.size", f"{width}x{height} is more than {MAX_ATLAS_TEXELS} texels")
    pad = v.int(a["padding"], "atlas.padding", 0, 64)
    v.str(a["texel_origin"], "atlas.texel_origin", MAX_TEXT)
    v.dict(a["layers"], "atlas.layers", tuple(LAYERS) + ("albedo_srgb",))
    files = {}
    for name, channels in list(LAYERS.items()) + [("albedo_srgb", 3)]:
        where, ext = f"atlas.layers.{name}", "png" if name == "albedo_srgb" else "exr"
        entry = v.dict(a["layers"][name], where, ("channels", "type"))
        v.equal(entry["channels"], f"{where}.channels", channels)
        v.equal(entry["type"], f"{where}.type", LAYER_TYPES[ext])
        raw = width * height * channels * (4 if ext == "exr" else 1)
        files[name] = _file_entry(v, entry, where, f"atlas-{name.replace('_', '-')}", ext,
                                  raw + raw // 64 + IMAGE_OVERHEAD)
    coverage = {}
    for key, value in v.dict(a["coverage"], "atlas.coverage").items():
        coverage[v.key(key, "atlas.coverage key")] = v.num(value, f"atlas.coverage[{key!r}]", 0.0, 1.0)
    if len(coverage) > MAX_ENTRIES:
        v.fail("atlas.coverage", f"has more than {MAX_ENTRIES} entries")
    table, seen = [], {}
    for n, e in enumerate(v.list(a["cards"], "atlas.cards", 1)):
        where = f"atlas.cards[{n}]"
        v.dict(e, where, ("mesh", "index", "axis", "rect", "rect_min", "rect_max", "near", "far"))
        mesh = v.key(e["mesh"], f"{where}.mesh")
        if mesh not in coverage:
            v.fail(f"{where}.mesh", "has no atlas.coverage entry")
        index = v.int(e["index"], f"{where}.index", 0, MAX_CARD_INDEX)
        seen.setdefault(mesh, set()).add(index)
        x, y, w, h = v.ints(e["rect"], f"{where}.rect", 4, 0, MAX_ATLAS_SIDE)
        if w < 1 or h < 1 or x < pad or y < pad or x + w + pad > width or y + h + pad > height:
            v.fail(f"{where}.rect", f"{[x, y, w, h]} (with {pad} texels of padding) lies outside "
                                    f"the {width}x{height} atlas or is empty")
        lo, hi = v.vec(e["rect_min"], f"{where}.rect_min", 2), v.vec(e["rect_max"], f"{where}.rect_max", 2)
        near, far = v.num(e["near"], f"{where}.near"), v.num(e["far"], f"{where}.far")
        if (lo > hi).any() or near > far:
            v.fail(where, "has rect_min above rect_max or near beyond far")
        table.append({"mesh": mesh, "index": index, "axis": v.int(e["axis"], f"{where}.axis", 0, 5),
                      "rect": [x, y, w, h], "rect_min": lo.tolist(), "rect_max": hi.tolist(),
                      "near": near, "far": far})
    for mesh, indices in seen.items():
        count = sum(1 for e in table if e["mesh"] == mesh)
        if len(indices) != count or max(indices) != count - 1:
            v.fail("atlas.cards", f"of mesh {mesh} must be numbered 0..{count - 1} once each")
    return width, height, files, table, coverage


def _check_stats(v: _Values, s, totals: dict) -> float:
    """The bake's totals must be what the cache holds; returns the bake's seconds."""
    v.dict(s, "stats", ("objects", "unique_meshes", "bricks", "bytes", "seconds", "reused", "cards",
                        "texels", "coverage", "atlas"))
    for key, want in totals.items():
        if s[key] != want or type(s[key]) is not type(want):
            v.fail(f"stats.{key}", f"is {_short(s[key], 40)}, the cache holds {want!r}")
    v.int(s["reused"], "stats.reused", 0, totals["unique_meshes"])
    v.num(s["coverage"], "stats.coverage", 0.0, 1.0)
    return v.num(s["seconds"], "stats.seconds", 0.0, MAX_SECONDS)


def _check_mesh_stats(v: _Values, entries: list, meshes: dict):
    """Each mesh's per-mip stats (informational) must agree with its arrays, key by key."""
    for i, (entry, mesh) in enumerate(zip(entries, meshes.values())):
        where = f"meshes[{i}].stats"
        v.list(entry["stats"], where, MIP_COUNT, MIP_COUNT)
        for k, (got, want) in enumerate(zip(entry["stats"], mesh.stats())):
            for key, value in v.dict(got, f"{where}[{k}]").items():
                if key in want and (value != want[key] or type(value) is not type(want[key])):
                    v.fail(f"{where}[{k}].{key}", f"is {_short(value, 40)}, the arrays make "
                                                  f"{want[key]!r}")


def _decode(manifest: dict, mpath: Path) -> SceneBake:
    """Check every value of the manifest, then the files' sizes, then read the arrays and images."""
    v = _Values(mpath)
    v.dict(manifest, "manifest", ("generator", "units", "axes", "settings", "sdf", "meshes",
                                  "instances", "stats"))
    v.str(manifest["generator"], "generator", MAX_TEXT)
    v.equal(manifest["units"], "units", "metres")
    v.str(manifest["axes"], "axes", MAX_TEXT)
    settings = _settings(v, manifest["settings"])
    sdf = v.dict(manifest["sdf"], "sdf", ("brick_size", "brick_cells", "band_voxels", "encoding",
                                          "invalid_outside", "invalid_inside"))
    for key, want in (("brick_size", BRICK), ("brick_cells", BRICK_CELLS), ("encoding", ENCODING),
                      ("invalid_outside", INVALID_OUTSIDE), ("invalid_inside", INVALID_INSIDE)):
        v.equal(sdf[key], f"sdf.{key}", want)
    if v.num(sdf["band_voxels"], "sdf.band_voxels") != BAND_VOXELS:
        v.fail("sdf.band_voxels", f"must be {BAND_VOXELS:g}")

    meshes, arrays = {}, []
    for i, m in enumerate(v.list(manifest["meshes"], "meshes", 1)):
        key, mesh, mesh_arrays = _mesh(v, m, i)
        if key in meshes:
            v.fail(f"meshes[{i}].hash", "repeats an earlier mesh's")
        meshes[key] = mesh
        arrays += mesh_arrays
    instances = _instances(v, manifest["instances"], meshes)
    for i, m in enumerate(manifest["meshes"]):
        users = [x.name for x in instances if x.mesh == m["hash"]]
        if m["objects"] != users:
            v.fail(f"meshes[{i}].objects", f"must list the instances of the mesh, {_short(users)}")

    data_bytes = sum(int(np.prod(shape)) * dtype.itemsize for _, dtype, shape in arrays)
    if data_bytes > MAX_SDF_BYTES:
        v.fail("meshes", f"declare {data_bytes} bytes of SDF arrays, more than {MAX_SDF_BYTES}")
    npz_path, npz_sha, npz_size = _file_entry(v, sdf, "sdf", "sdf", "npz", MAX_SDF_BYTES)
    framing = ZIP_OVERHEAD * (len(arrays) + 1)
    if not data_bytes <= npz_size <= data_bytes + framing:
        v.fail("sdf.size", f"{npz_size} does not fit its arrays ({data_bytes} bytes and at most "
                           f"{framing} of framing)")

    atlas_info, cards_total = None, {"cards": 0, "texels": 0, "atlas": [0, 0]}
    if "atlas" in manifest:
        atlas_info = _atlas_info(v, manifest["atlas"])
        width, height, files, table, coverage = atlas_info
        cards_total = {"cards": len(table), "texels": sum(e["rect"][2] * e["rect"][3] for e in table),
                       "coverage": round(min(coverage.values()), 4), "atlas": [width, height]}
        for n, x in enumerate(instances):
            if x.cards not in coverage and x.cards != NO_CARDS:
                v.fail(f"instances[{n}].cards", "names no cards of this cache")
    kept = sum(shape[0] for name, _, shape in arrays if name.endswith("_bricks"))
    cells = sum(int(np.prod(shape)) for name, _, shape in arrays if name.endswith("_indirection"))
    seconds = _check_stats(v, manifest["stats"], {
        "objects": len(instances), "unique_meshes": len(meshes), "bricks": kept,
        "bytes": kept * BRICK ** 3 + 4 * cells, **cards_total})

    # Every file the manifest names is a regular file of the declared size before any is read.
    named = [(npz_path, npz_sha, npz_size)] + (list(atlas_info[2].values()) if atlas_info else [])
    for path, _, size in named:
        st = _regular(path)
        if st.st_size != size:
            raise CacheError(f"{path}: {st.st_size} bytes, the manifest says {size} (truncated or "
                             f"modified)")
    loaded = _read_npz(npz_path, npz_sha, npz_size, arrays)
    for i, mesh in enumerate(meshes.values()):
        for k, mip in enumerate(mesh.mips):
            ind, bricks = loaded[f"mesh{i}_mip{k}_indirection"], loaded[f"mesh{i}_mip{k}_bricks"]
            slots = ind[ind >= 0]
            if (ind < INVALID_INSIDE).any() or len(slots) != len(bricks) or (
                    len(slots) and (np.bincount(slots, minlength=len(bricks)) != 1).any()):
                raise CacheError(f"{npz_path}: mesh{i}_mip{k}_indirection must point at each of its "
                                 f"{len(bricks)} bricks once (and hold -1 or -2 elsewhere)")
            mip.indirection, mip.bricks = ind, bricks
    _check_mesh_stats(v, manifest["meshes"], meshes)
    atlas, cards = None, {}
    if atlas_info is not None:
        atlas = _read_atlas(atlas_info)
        cards = split_atlas(atlas, atlas_info[4])
    return SceneBake(settings, meshes, instances, seconds, cards=cards, atlas=atlas)


def _read_verified(path: Path, sha: str, size: int):
    """The open file, at offset 0, once its size and SHA-256 (hashed in chunks) match the
    manifest."""
    fh = _open_regular(path, size)
    try:
        digest, total = hashlib.sha256(), 0
        while total <= size:
            chunk = fh.read(min(_CHUNK, size + 1 - total))
            if not chunk:
                break
            digest.update(chunk)
            total += len(chunk)
        if total != size or digest.hexdigest() != sha:
            raise CacheError(f"{path}: truncated or modified (size/checksum differ from the manifest)")
        fh.seek(0)
        return fh
    except BaseException:
        fh.close()
        raise


def _zip_directory(fh, path: Path, size: int, count: int):
    """Check the zip's end record before zipfile reads the directory: no comment, one disk,
    exactly `count` entries and a directory no larger than they need (at most 512 bytes each)."""
    def refuse(why):
        raise CacheError(f"{path}: not a .npz of this cache ({why})")

    if size < 22:
        refuse("too short for a zip file")
    fh.seek(size - 22)
    sig, disk, cd_disk, n_disk, n_total, cd_size, cd_offset, comment = struct.unpack("<4s4H2LH", fh.read(22))
    if sig != b"PK\x05\x06" or comment:
        refuse("no zip end record at the end of the file")
    if 0xFFFF in (n_disk, n_total) or 0xFFFFFFFF in (cd_size, cd_offset):     # zip64
        if size < 22 + 20 + 56:
            refuse("truncated zip64 records")
        fh.seek(size - 42)
        lsig, _, where, _ = struct.unpack("<4sLQL", fh.read(20))
        if lsig != b"PK\x06\x07" or where > size - 42 - 56:
            refuse("bad zip64 locator")
        fh.seek(where)
        (rsig, _, _, _, disk, cd_disk, n_disk, n_total, cd_size,
         cd_offset) = struct.unpack("<4sQ2H2L4Q", fh.read(56))
        if rsig != b"PK\x06\x06":
            refuse("bad zip64 end record")
    if disk or cd_disk or n_disk != n_total:
        refuse("spans several disks")
    if n_total != count:
        refuse(f"{n_total} members, the manifest names {count} arrays")
    if cd_size > 512 * count or cd_offset + cd_size > size:
        refuse(f"a directory of {cd_size} bytes at {cd_offset}")
    fh.seek(0)


def _read_npz(path: Path, sha: str, size: int, arrays: list) -> dict:
    """{name: array} of the .npz, every member checked before it is read: members are stored
    (np.savez: nothing to inflate, so no member can expand beyond the file), and each member's
    size and .npy header (version, dtype, shape, order) are exactly what the manifest declares.
    Never unpickles: only the header is parsed, then raw bytes are read."""
    want = {f"{name}.npy": (name, dtype, tuple(shape)) for name, dtype, shape in arrays}
    out = {}
    with _read_verified(path, sha, size) as fh:
        _zip_directory(fh, path, size, len(want))
        try:
            zf = zipfile.ZipFile(fh)
        except Exception as exc:
            raise CacheError(f"{path}: not a readable .npz ({_short(exc)})") from exc
        with zf:
            infos = zf.infolist()
            if sorted(i.filename for i in infos) != sorted(want):
                raise CacheError(f"{path}: holds arrays {_short(sorted(i.filename for i in infos), 120)}, "
                                 f"the manifest names {_short(sorted(want), 120)}")
            for info in infos:
                name, dtype, shape = want[info.filename]
                out[name] = _read_member(zf, info, path, name, dtype, shape)
    return out


def _read_member(zf, info, path: Path, name: str, dtype, shape: tuple) -> np.ndarray:
    nbytes = int(np.prod(shape)) * dtype.itemsize

    def refuse(why):
        raise CacheError(f"{path}: array {name!r} {why}")

    if (info.compress_type != zipfile.ZIP_STORED or info.flag_bits & 0x1
            or info.compress_size != info.file_size):
        refuse("is compressed or encrypted; the cache stores arrays as they are (np.savez)")
    if not nbytes + 10 <= info.file_size <= nbytes + 12 + MAX_NPY_HEADER:
        refuse(f"is {info.file_size} bytes, {dtype}{shape} needs {nbytes} and a header")
    try:
        with zf.open(info) as member:
            magic = member.read(8)
            major, minor = np.lib.format.read_magic(io.BytesIO(magic))
            if (major, minor) not in ((1, 0), (2, 0)):
                refuse(f"is a .npy of version {major}.{minor}, not 1.0 or 2.0")
            length = member.read(2 if major == 1 else 4)
            header_len = struct.unpack("<H" if major == 1 else "<I", length)[0]
            if header_len > MAX_NPY_HEADER:
                refuse(f"has a .npy header of {header_len} bytes (at most {MAX_NPY_HEADER})")
            header = io.BytesIO(length + member.read(header_len))
            read_header = (np.lib.format.read_array_header_1_0 if major == 1
                           else np.lib.format.read_array_header_2_0)
            got_shape, fortran, got_dtype = read_header(header)
            if got_dtype != dtype or tuple(got_shape) != shape or (fortran and len(shape) > 1):
                refuse(f"is {got_dtype}{tuple(got_shape)}{' (Fortran order)' if fortran else ''}, "
                       f"the manifest says {dtype}{shape}")
            if info.file_size != len(magic) + len(length) + header_len + nbytes:
                refuse(f"is {info.file_size} bytes, its header and {dtype}{shape} make "
                       f"{len(magic) + len(length) + header_len + nbytes}")
            data = member.read(nbytes)
            if len(data) != nbytes or member.read(1):       # reading to the end checks its CRC
                refuse("is truncated")
    except CacheError:
        raise
    except Exception as exc:        # zipfile.BadZipFile (CRC), ValueError from the header, ...
        raise CacheError(f"{path}: array {name!r} is unreadable ({_short(exc)})") from exc
    return np.frombuffer(data, dtype).reshape(shape).copy()


def _exr_header(fh, path: Path, width: int, height: int, channels: int):
    """Check an OpenEXR file's header bytes before OpenImageIO opens it (OpenEXR sizes its
    tables from the header): single-part scanline, data window 0..width-1 x 0..height-1,
    `channels` float channels sampled 1x1, the header within 64 KiB."""
    def refuse(why):
        raise CacheError(f"{path}: {why}, the manifest says a {width}x{height} {channels}-channel "
                         f"float OpenEXR image")

    head = fh.read(1 << 16)
    if len(head) < 8 or head[:4] != b"\x76\x2f\x31\x01":
        refuse("not an OpenEXR file")
    if struct.unpack_from("<I", head, 4)[0] & ~0x400 != 2:
        refuse("an OpenEXR file that is tiled, deep or multi-part")
    pos, attrs = 8, {}
    while True:
        end = head.find(b"\0", pos, pos + 256)
        if end < 0:
            refuse("an OpenEXR header longer than 64 KiB or malformed")
        if end == pos:
            break
        name, tend = head[pos:end], head.find(b"\0", end + 1, end + 257)
        if tend < 0 or tend + 5 > len(head):
            refuse("an OpenEXR header longer than 64 KiB or malformed")
        (n,) = struct.unpack_from("<i", head, tend + 1)
        if not 0 <= n <= len(head) - tend - 5:
            refuse("an OpenEXR header longer than 64 KiB or malformed")
        attrs[name] = (head[end + 1:tend], head[tend + 5:tend + 5 + n])
        pos = tend + 5 + n
    if attrs.get(b"dataWindow", (b"", b""))[0] != b"box2i" or len(attrs[b"dataWindow"][1]) != 16:
        refuse("an OpenEXR header without a data window")
    window = struct.unpack("<4i", attrs[b"dataWindow"][1])
    if window != (0, 0, width - 1, height - 1):
        refuse(f"an OpenEXR data window {window}")
    kind, chlist = attrs.get(b"channels", (b"", b""))
    found, pos = [], 0
    while kind == b"chlist" and pos < len(chlist) and chlist[pos:pos + 1] != b"\0":
        end = chlist.find(b"\0", pos)
        if end < 0 or end + 17 > len(chlist):
            break
        ptype, _, xs, ys = struct.unpack_from("<iB3xii", chlist, end + 1)
        found.append((ptype, xs, ys))
        pos = end + 17
    if len(found) != channels or any(c != (2, 1, 1) for c in found):
        refuse(f"an OpenEXR image of channels {found} (type, x and y sampling)")
    fh.seek(0)


def _read_image(oiio, path: Path, width: int, height: int, channels: int) -> np.ndarray:
    """One atlas layer: its spec (format, size, channels, names, float) checked against the
    manifest before any pixel is read; texels must be finite."""
    names = tuple(oiio.ImageSpec(1, 1, channels, oiio.FLOAT).channelnames)
    try:
        inp = oiio.ImageInput.open(str(path))
    except Exception as exc:
        raise CacheError(f"{path}: not a readable image ({_short(exc)})") from exc
    if inp is None:
        raise CacheError(f"{path}: not a readable image ({_short(oiio.geterror())})")
    try:
        spec = inp.spec()
        got = (inp.format_name(), spec.width, spec.height, spec.nchannels, spec.x, spec.y, spec.z,
               spec.depth, bool(spec.deep), str(spec.format), tuple(spec.channelnames))
        want = ("openexr", width, height, channels, 0, 0, 0, 1, False, "float", names)
        if got != want or any(str(f) != "float" for f in spec.channelformats):
            raise CacheError(f"{path}: image is {_short(got, 160)}, the manifest says {want}")
        data = inp.read_image(format=oiio.FLOAT)
        error = "" if data is not None else inp.geterror()
    except CacheError:
        raise
    except Exception as exc:
        raise CacheError(f"{path}: not a readable image ({_short(exc)})") from exc
    finally:
        inp.close()
    if not isinstance(data, np.ndarray) or data.shape != (height, width, channels):
        raise CacheError(f"{path}: image unreadable or of shape {getattr(data, 'shape', None)} "
                         f"({_short(error)}), the manifest says {(height, width, channels)}")
    if not np.isfinite(data).all():
        raise CacheError(f"{path}: holds texels that are NaN or infinite")
    return np.ascontiguousarray(data, dtype=np.float32)


def _read_atlas(info) -> Atlas:
    """The atlas layers (each file verified, its header and spec checked, then decoded) and the
    card table as the manifest checked it. The sRGB PNG is verified and its spec checked."""
    import OpenImageIO as oiio

    width, height, files, table, _ = info
    layers = {}
    for name, channels in LAYERS.items():
        path, sha, size = files[name]
        with _read_verified(path, sha, size) as fh:
            _exr_header(fh, path, width, height, channels)
        layers[name] = _read_image(oiio, path, width, height, channels)
    path, sha, size = files["albedo_srgb"]
    _read_verified(path, sha, size).close()
    _png_spec(oiio, path, width, height)
    return Atlas((width, height), layers, table)


def _png_spec(oiio, path: Path, width: int, height: int):
    """The sRGB PNG is for people to look at: its spec is checked, its pixels are not decoded."""
    try:
        inp = oiio.ImageInput.open(str(path))
        if inp is None:
            raise CacheError(f"{path}: not a readable image ({_short(oiio.geterror())})")
        try:
            spec = inp.spec()
            got = (inp.format_name(), spec.width, spec.height, spec.nchannels, str(spec.format))
        finally:
            inp.close()
    except CacheError:
        raise
    except Exception as exc:
        raise CacheError(f"{path}: not a readable image ({_short(exc)})") from exc
    if got != ("png", width, height, 3, "uint8"):
        raise CacheError(f"{path}: image is {_short(got)}, the manifest says a {width}x{height} "
                         f"3-channel 8-bit PNG")
