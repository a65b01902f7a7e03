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
from .bake import BakeSettings, Instance, SceneBake
from .sdf import BAND_VOXELS, BRICK, BRICK_CELLS, INVALID_INSIDE, MeshSDF, SDFMip

FORMAT = "lumen-gi-cache"
VERSION = 1
MANIFEST = "manifest.json"


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
                     "inside_fraction": bake.settings.inside_fraction},
        "sdf": {"brick_size": BRICK, "brick_cells": BRICK_CELLS, "band_voxels": BAND_VOXELS,
                "encoding": "uint8 code c -> distance (c - 127.5) / 127.5 * band",
                "invalid_outside": -1, "invalid_inside": INVALID_INSIDE,
                "file": npz_name, "sha256": digest, "size": len(payload)},
        "meshes": meshes,
        "instances": [{"object": x.name, "mesh": x.mesh,
                       "matrix_world": np.asarray(x.matrix_world).tolist()} for x in bake.instances],
        "stats": bake.stats(),
    }
    try:
        _atomic_write(folder / npz_name, payload)
        _atomic_write(folder / MANIFEST, json.dumps(manifest, indent=1).encode())
    except OSError as exc:
        raise CacheError(f"cannot write cache in {folder}: {exc.strerror or exc}") from exc
    for stale in folder.glob("sdf-*.npz"):
        if stale.name != npz_name:
            try:
                stale.unlink()
            except OSError:
                pass   # an old file left behind is harmless: no manifest names it
    return folder / MANIFEST


def _atomic_write(path: Path, data: bytes):
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
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


def _decode(manifest, folder: Path) -> SceneBake:
    info = manifest["sdf"]
    npz_path = folder / str(info["file"])
    if Path(info["file"]).name != info["file"]:
        raise CacheError(f"{folder / MANIFEST}: array file name {info['file']!r} leaves the folder")
    try:
        payload = npz_path.read_bytes()
    except OSError as exc:
        raise CacheError(f"{npz_path}: cannot read ({exc.strerror or exc})") from exc
    if len(payload) != info["size"] or hashlib.sha256(payload).hexdigest() != info["sha256"]:
        raise CacheError(f"{npz_path}: truncated or modified (size/checksum differ from the manifest)")
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
    instances = []
    for x in manifest["instances"]:
        if x["mesh"] not in meshes:
            raise CacheError(f"{folder / MANIFEST}: instance {x['object']!r} names unknown mesh")
        mat = np.array(x["matrix_world"], float)
        if mat.shape != (4, 4):
            raise CacheError(f"{folder / MANIFEST}: instance {x['object']!r} matrix is not 4x4")
        instances.append(Instance(str(x["object"]), x["mesh"], mat))
    s = manifest["settings"]
    settings = BakeSettings(float(s["voxel_density"]), int(s["max_resolution"]),
                            float(s["inside_fraction"]))
    stats = manifest.get("stats", {})
    return SceneBake(settings, meshes, instances, float(stats.get("seconds", 0.0)))
