"""The cache on disk: a folder with `manifest.json` and one `.npz` of arrays (no pickle).

Writing is atomic at the manifest: arrays go to a content-named file first, then the manifest is
replaced in one rename, then files no manifest names are removed. A crash or a full disk leaves
the previous cache readable. Reading checks the format, version, the arrays' checksum, and that
every array has the dtype and shape the manifest says; anything else is a CacheError that names
the file. The format is documented in docs/cache-format.md.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from . import __version__
from .atlas import LAYERS, PADDING, Atlas, split_atlas
from .bake import BakeSettings, Instance, SceneBake
from .sdf import BAND_VOXELS, BRICK, BRICK_CELLS, INVALID_INSIDE, MeshSDF, SDFMip

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
                     "max_cards": bake.settings.max_cards},
        "sdf": {"brick_size": BRICK, "brick_cells": BRICK_CELLS, "band_voxels": BAND_VOXELS,
                "encoding": "uint8 code c -> distance (c - 127.5) / 127.5 * band",
                "invalid_outside": -1, "invalid_inside": INVALID_INSIDE,
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


def read_cache(folder) -> SceneBake:
    """Read and validate a cache folder (or its manifest.json path)."""
    folder = Path(folder)
    mpath = folder if folder.name == MANIFEST else folder / MANIFEST
    folder = mpath.parent
    try:
        manifest = json.loads(mpath.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise CacheError(f"{mpath}: no cache manifest here") from exc
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CacheError(f"{mpath}: not a Lumen GI cache manifest ({exc})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise CacheError(f"{mpath}: not a Lumen GI cache manifest")
    if manifest.get("version") != VERSION:
        raise CacheError(f"{mpath}: cache version {manifest.get('version')!r}, this build reads "
                         f"version {VERSION}; bake again")
    try:
        return _decode(manifest, folder)
    except CacheError:
        raise
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise CacheError(f"{mpath}: malformed manifest ({type(exc).__name__}: {exc})") from exc


def _read_verified(folder: Path, entry: dict):
    """(path, bytes) of a file the manifest names, checked against its size and SHA-256."""
    name = str(entry["file"])
    if Path(name).name != name:
        raise CacheError(f"{folder / MANIFEST}: file name {name!r} leaves the folder")
    path = folder / name
    try:
        payload = path.read_bytes()
    except OSError as exc:
        raise CacheError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    if len(payload) != entry["size"] or hashlib.sha256(payload).hexdigest() != entry["sha256"]:
        raise CacheError(f"{path}: truncated or modified (size/checksum differ from the manifest)")
    return path, payload


def _decode(manifest, folder: Path) -> SceneBake:
    npz_path, payload = _read_verified(folder, manifest["sdf"])
    try:
        arrays = np.load(io.BytesIO(payload), allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise CacheError(f"{npz_path}: not a readable .npz ({exc})") from exc

    def get(name, dtype, shape):
        if name not in arrays.files:
            raise CacheError(f"{npz_path}: array {name!r} is missing")
        a = arrays[name]
        if a.dtype != dtype or a.shape != tuple(shape):
            raise CacheError(f"{npz_path}: array {name!r} is {a.dtype}{a.shape}, manifest says "
                             f"{np.dtype(dtype)}{tuple(shape)}")
        return a

    meshes = {}
    for m in manifest["meshes"]:
        mips = []
        for mip in m["mips"]:
            grid = [int(x) for x in mip["brick_grid"]]
            count = int(mip["bricks_kept"])
            ind = get(mip["indirection"], np.int32, grid)
            bricks = get(mip["bricks"], np.uint8, (count, BRICK, BRICK, BRICK))
            if ind.size and (ind.min() < INVALID_INSIDE or ind.max() >= count):
                raise CacheError(f"{npz_path}: {mip['indirection']} points outside its bricks")
            res = tuple(int(x) for x in mip["resolution"])
            if tuple(n * BRICK_CELLS for n in grid) != res:
                raise CacheError(f"{npz_path}: {mip['indirection']} does not match resolution {res}")
            mips.append(SDFMip(float(mip["voxel_size"]), res, ind, bricks))
        meshes[m["hash"]] = MeshSDF(
            origin=np.array(m["origin"], float), bounds_min=np.array(m["bounds_min"], float),
            bounds_max=np.array(m["bounds_max"], float), two_sided=bool(m["two_sided"]),
            mips=mips, requested_resolution=tuple(m["requested_resolution"]))
    atlas, cards = None, {}
    if "atlas" in manifest:
        atlas = _read_atlas(folder, manifest["atlas"])
        cards = split_atlas(atlas, manifest["atlas"]["coverage"])
    instances = []
    for x in manifest["instances"]:
        if x["mesh"] not in meshes:
            raise CacheError(f"{folder / MANIFEST}: instance {x['object']!r} names unknown mesh")
        mat = np.array(x["matrix_world"], float)
        if mat.shape != (4, 4):
            raise CacheError(f"{folder / MANIFEST}: instance {x['object']!r} matrix is not 4x4")
        instances.append(Instance(str(x["object"]), x["mesh"], mat, str(x.get("cards", ""))))
    s = manifest["settings"]
    settings = BakeSettings(float(s["voxel_density"]), int(s["max_resolution"]),
                            float(s["inside_fraction"]), float(s["texel_density"]),
                            int(s["texel_budget"]), int(s["max_cards"]))
    stats = manifest.get("stats", {})
    return SceneBake(settings, meshes, instances, float(stats.get("seconds", 0.0)),
                     cards=cards, atlas=atlas)


def _read_atlas(folder: Path, info: dict) -> Atlas:
    import OpenImageIO as oiio

    width, height = (int(x) for x in info["size"])
    layers = {}
    for name, channels in LAYERS.items():
        path, _ = _read_verified(folder, info["layers"][name])
        inp = oiio.ImageInput.open(str(path))
        if inp is None:
            raise CacheError(f"{path}: not a readable image ({oiio.geterror()})")
        try:
            data = inp.read_image(format=oiio.FLOAT)
        finally:
            inp.close()
        if data is None or data.shape != (height, width, channels):
            raise CacheError(f"{path}: image is {getattr(data, 'shape', None)}, manifest says "
                             f"{(height, width, channels)}")
        layers[name] = np.ascontiguousarray(data, dtype=np.float32)
    for e in info["cards"]:
        x, y, w, h = e["rect"]
        if x < 0 or y < 0 or x + w > width or y + h > height:
            raise CacheError(f"{folder / MANIFEST}: a card of mesh {e['mesh']} lies outside the atlas")
    return Atlas((width, height), layers, list(info["cards"]))
