"""Scene bake: every object's mesh SDF, one bake per unique mesh content (instances share it).

Plain data in, plain data out: `operators/` extracts `ObjectInput`s from Blender; scripts can
build them from anything. A mesh is identified by a hash of its geometry, its bake options and
the algorithm version, so linked duplicates and instances bake once and unchanged meshes are
reused from a previous bake.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from . import __version__
from .geometry import MeshError, clean_mesh
from .sdf import DEFAULT_MAX_RESOLUTION, BakeCancelled, MeshSDF, bake_mesh_sdf, plan_resolution
from .sign import INSIDE_FRACTION

ALGORITHM_VERSION = 1   # bump when a change makes old bakes differ from new ones


@dataclass(frozen=True)
class BakeSettings:
    voxel_density: float = 20.0          # voxels per metre at resolution scale 1
    max_resolution: int = DEFAULT_MAX_RESOLUTION
    inside_fraction: float = INSIDE_FRACTION


@dataclass
class ObjectInput:
    name: str
    vertices: np.ndarray                 # (V, 3) local space, metres
    triangles: np.ndarray                # (T, 3)
    matrix_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    two_sided: bool = False
    resolution_scale: float = 1.0


@dataclass
class Instance:
    name: str
    mesh: str                            # content hash of its mesh
    matrix_world: np.ndarray


@dataclass
class SceneBake:
    settings: BakeSettings
    meshes: dict                         # hash -> MeshSDF
    instances: list                      # [Instance]
    seconds: float = 0.0
    reused: int = 0                      # unique meshes taken from a previous bake
    warnings: list = field(default_factory=list)

    def stats(self) -> dict:
        """Totals for the N-panel and the manifest (mip 0 + all mips bytes)."""
        bricks = sum(s["bricks_kept"] for m in self.meshes.values() for s in m.stats())
        nbytes = sum(s["bytes"] for m in self.meshes.values() for s in m.stats())
        return {"objects": len(self.instances), "unique_meshes": len(self.meshes),
                "bricks": int(bricks), "bytes": int(nbytes), "seconds": round(self.seconds, 3),
                "reused": self.reused}


class SceneBakeError(ValueError):
    """The scene cannot be baked; `problems` lists (object name, reason)."""

    def __init__(self, problems):
        self.problems = list(problems)
        super().__init__("; ".join(f"{name}: {why}" for name, why in self.problems))


def mesh_hash(obj: ObjectInput, settings: BakeSettings) -> str:
    """Content hash of everything that changes a mesh's bake."""
    h = hashlib.sha1()
    v = np.ascontiguousarray(obj.vertices, dtype=np.float64)
    t = np.ascontiguousarray(obj.triangles, dtype=np.int64)
    for arr in (v, t):
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    h.update(repr((bool(obj.two_sided), float(obj.resolution_scale), asdict(settings),
                   ALGORITHM_VERSION)).encode())
    return h.hexdigest()[:20]


def bake_scene(objects, settings: BakeSettings = BakeSettings(), *, previous: SceneBake = None,
               progress=None) -> SceneBake:
    """Bake every object's SDF; meshes with the same content hash are baked once.

    All inputs are checked before any baking starts; problems are raised together as a
    SceneBakeError naming each object. progress(fraction, message) may raise BakeCancelled.
    """
    start = time.perf_counter()
    objects = list(objects)
    if not objects:
        raise SceneBakeError([("scene", "no visible mesh objects to bake")])
    problems, instances, todo = [], [], {}
    for obj in objects:
        m = np.asarray(obj.matrix_world, dtype=np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            problems.append((obj.name, "world matrix is not a finite 4x4 matrix"))
            continue
        try:
            # Validate here so that one bad object stops the bake before any time is spent.
            clean_mesh(obj.vertices, obj.triangles)
            plan_resolution(np.ones(3), settings.voxel_density, obj.resolution_scale,
                            settings.max_resolution)
        except MeshError as exc:
            problems.append((obj.name, str(exc)))
            continue
        key = mesh_hash(obj, settings)
        instances.append(Instance(obj.name, key, m))
        todo.setdefault(key, obj)
    if problems:
        raise SceneBakeError(problems)

    meshes, warnings, reused = {}, [], 0
    old = previous.meshes if previous is not None and previous.settings == settings else {}
    cost = {k: max(len(o.triangles), 1) ** 0.5 for k, o in todo.items() if k not in old}
    total, done = sum(cost.values()) or 1.0, 0.0
    for key, obj in todo.items():
        if key in old:
            meshes[key], reused = old[key], reused + 1
            continue
        span = cost[key] / total

        def sub(f, done=done, span=span, name=obj.name):
            if progress:
                progress(done + span * f, name)

        sub(0.0)
        sdf = bake_mesh_sdf(obj.vertices, obj.triangles, voxel_density=settings.voxel_density,
                            resolution_scale=obj.resolution_scale, two_sided=obj.two_sided,
                            max_resolution=settings.max_resolution,
                            inside_fraction=settings.inside_fraction, progress=sub)
        if sdf.clamped:
            warnings.append((obj.name, f"resolution {'x'.join(map(str, sdf.requested_resolution))} "
                             f"clamped to {'x'.join(map(str, sdf.mips[0].resolution))} voxels"))
        if sdf.dropped_degenerate:
            warnings.append((obj.name, f"{sdf.dropped_degenerate} zero-area faces ignored"))
        meshes[key] = sdf
        done += span
    if progress:
        progress(1.0, "")
    return SceneBake(settings, meshes, instances, time.perf_counter() - start, reused, warnings)


__all__ = ["BakeSettings", "ObjectInput", "Instance", "SceneBake", "SceneBakeError", "BakeCancelled",
           "MeshSDF", "bake_scene", "mesh_hash", "__version__"]
