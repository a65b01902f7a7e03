"""Scene bake: every object's mesh SDF, one bake per unique mesh content (instances share it).

Plain data in, plain data out: `operators/` extracts `ObjectInput`s from Blender; scripts can
build them from anything. A mesh is identified by a hash of its geometry, its bake options and
the algorithm version, so linked duplicates and instances bake once and unchanged meshes are
reused from a previous bake.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from . import __version__
from . import cards as cardlib
from .atlas import Atlas, build_atlas
from .geometry import MeshError, clean_mesh, orient_triangles
from .sdf import DEFAULT_MAX_RESOLUTION, BakeCancelled, MeshSDF, bake_mesh_sdf, plan_resolution
from .sign import INSIDE_FRACTION

ALGORITHM_VERSION = 8   # bump when a change makes old bakes differ from new ones
SDF_SHARE = 0.7         # of the progress bar; the cards take the rest


@dataclass(frozen=True)
class BakeSettings:
    voxel_density: float = 20.0          # voxels per metre at resolution scale 1
    max_resolution: int = DEFAULT_MAX_RESOLUTION
    inside_fraction: float = INSIDE_FRACTION
    texel_density: float = 20.0          # card texels per metre of world size (UE: about 20)
    texel_budget: int = 2048 * 2048      # all cards of the scene together
    max_cards: int = 32                  # per mesh (UE: 12 by default, 32 at most)
    min_card_size: float = 0.0           # metres: smaller objects get no cards unless they
                                         # emit (UE: MeshCardsMinSize, 10 cm); 0: all get them


@dataclass
class ObjectInput:
    name: str
    vertices: np.ndarray                 # (V, 3) local space, metres
    triangles: np.ndarray                # (T, 3)
    matrix_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    two_sided: bool = False
    resolution_scale: float = 1.0
    # Surface attributes for the mesh cards (all optional):
    normals: Optional[np.ndarray] = None       # (T, 3, 3) per-corner normals, local space
    uvs: Optional[np.ndarray] = None           # (T, 3, 2) per-corner UVs of the texture UV map
    material_ids: Optional[np.ndarray] = None  # (T,) index into `materials`
    materials: list = field(default_factory=list)   # [materials.Material]; empty: plain grey
    colors: Optional[np.ndarray] = None        # (T, 3, 3) per-corner linear RGB: the colour
                                               # attribute of Material.vertex_colors materials
    # (T, 3, 4) per-corner tangent and bitangent sign for normal maps (the G-buffer's only: not
    # part of any bake hash)
    tangents: Optional[np.ndarray] = None
    # Seen by camera rays (Blender's Object > Visibility > Camera): the preview's G-buffer skips
    # it, its SDF and cards still block and bounce light. Not part of any bake hash.
    camera_visible: bool = True
    # A holdout for camera rays (Object > Visibility > Holdout, or a holdout collection in the
    # view layer): transparent (alpha 0) where it is nearest, it hides what is behind it and
    # still casts and bounces light. Not part of any bake hash.
    holdout: bool = False
    # Casts shadows (Object > Visibility > Ray Visibility > Shadow): off, light and sky
    # visibility cones pass it (a window pane, a light blocker); it still bounces and blocks GI.
    # Not part of any bake hash.
    casts_shadow: bool = True
    # Seen by diffuse rays (Object > Visibility > Ray Visibility > Diffuse): off, GI rays pass
    # it as if it were not there (no bounce light from it, nor occlusion of others' bounce
    # light); it still casts shadows (as Shadow says) and receives light. Not part of any hash.
    diffuse_visible: bool = True
    # The share of light its cut-outs' holes let through one layer of its surface
    # (materials.shadow_transmission): shadow cones pass it by that much. Not part of any hash.
    shadow_transmission: float = 0.0


NO_CARDS = "0"                           # Instance.cards of an object too small for cards


@dataclass
class Instance:
    name: str
    mesh: str                            # content hash of its mesh's SDF
    matrix_world: np.ndarray
    cards: str = ""                      # content hash of its mesh's cards (NO_CARDS: none)


@dataclass
class SceneBake:
    settings: BakeSettings
    meshes: dict                         # SDF hash -> MeshSDF
    instances: list                      # [Instance]
    seconds: float = 0.0
    reused: int = 0                      # unique meshes taken from a previous bake
    warnings: list = field(default_factory=list)
    cards: dict = field(default_factory=dict)   # cards hash -> cards.MeshCards
    atlas: Optional[Atlas] = None

    def stats(self) -> dict:
        """Totals for the N-panel and the manifest (mip 0 + all mips bytes)."""
        bricks = sum(s["bricks_kept"] for m in self.meshes.values() for s in m.stats())
        nbytes = sum(s["bytes"] for m in self.meshes.values() for s in m.stats())
        cover = [mc.coverage for mc in self.cards.values()]
        return {"objects": len(self.instances), "unique_meshes": len(self.meshes),
                "bricks": int(bricks), "bytes": int(nbytes), "seconds": round(self.seconds, 3),
                "reused": self.reused, "cards": sum(len(mc.cards) for mc in self.cards.values()),
                "texels": sum(mc.texels for mc in self.cards.values()),
                "coverage": round(min(cover), 4) if cover else 0.0,
                "atlas": list(self.atlas.size) if self.atlas is not None else [0, 0]}


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
    sdf_settings = (settings.voxel_density, settings.max_resolution, settings.inside_fraction)
    h.update(repr((bool(obj.two_sided), float(obj.resolution_scale), sdf_settings,
                   sdf_scale(obj.matrix_world), ALGORITHM_VERSION)).encode())
    return h.hexdigest()[:20]


def sdf_scale(matrix) -> float:
    """The world scale an SDF is baked for: world_scale rounded to a half octave (1 stays 1).

    Voxel density is per metre of world size, as texel density is: the SDF is baked in local
    space, so a mesh scaled up 6.4x (an imported scan in its file's units) baked at 20 voxels
    per local metre had 32 cm voxels in the scene, the Stanford bunny 3 voxels across, and its
    shadow cones saw a blob 16 cm wider than the bunny (their half-voxel margin) around its
    base. Rounded so that instances of one mesh at similar scales still share one bake (within
    +-19% of the asked density); objects scaled more apart bake apart, as their cards do."""
    s = world_scale(matrix)
    if not (np.isfinite(s) and s > 0):
        return 1.0
    return float(2.0 ** (np.round(2.0 * np.log2(s)) / 2.0))


def context_key(key: str) -> str:
    """The bake key of a mesh whose orientation depends on what it holds (an inward-facing
    shell around other objects: a room seen from inside; see bake_scene's scene_points)."""
    return hashlib.sha1((key + ":holds others").encode()).hexdigest()[:20]


def world_scale(matrix) -> float:
    """Largest axis scale of a 4x4 world matrix: card texels are per metre of world size."""
    return float(np.linalg.norm(np.asarray(matrix, float)[:3, :3], axis=0).max())


def cards_hash(obj: ObjectInput, sdf_key: str, settings: BakeSettings, digests=None) -> str:
    """Content hash of everything that changes a mesh's cards: geometry (via the SDF key),
    surface attributes, materials, card settings (the budget too: it scales resolutions) and
    the world scale (texels per metre). digests: {id(material): digest} memo for one bake, so a
    texture shared by many objects is hashed once."""
    digests = {} if digests is None else digests
    h = hashlib.sha1(sdf_key.encode())
    for arr in (obj.normals, obj.uvs, obj.material_ids, obj.colors):
        h.update(b"-" if arr is None else np.ascontiguousarray(arr).tobytes())
    for m in obj.materials:
        if id(m) not in digests:
            digests[id(m)] = m.digest()
        h.update(digests[id(m)])
    h.update(repr((settings.texel_density, settings.texel_budget, settings.max_cards,
                   round(world_scale(obj.matrix_world), 6), ALGORITHM_VERSION)).encode())
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
    problems, instances, todo, card_todo, digests = [], [], {}, {}, {}
    warnings = []
    centres = [(o.name, _world_centre(o)) for o in objects]
    for obj in objects:
        m = np.asarray(obj.matrix_world, dtype=np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            problems.append((obj.name, "world matrix is not a finite 4x4 matrix"))
            continue
        try:
            # Validate here so that one bad object stops the bake before any time is spent.
            checked = clean_mesh(obj.vertices, obj.triangles)
            if checked.ignored_vertices:
                warnings.append((obj.name, f"{checked.ignored_vertices} loose vertices (no face "
                                           f"uses them) are NaN or infinite: ignored"))
            plan_resolution(np.ones(3), settings.voxel_density * sdf_scale(m), obj.resolution_scale,
                            settings.max_resolution)
        except MeshError as exc:
            problems.append((obj.name, str(exc)))
            continue
        key = mesh_hash(obj, settings)
        if not obj.two_sided and _faces_inward(obj) and _holds_others(obj, m, centres):
            # its orientation may depend on what it holds (scene_points): another key
            key = context_key(key)
        if too_small_for_cards(obj, m, settings.min_card_size):
            instances.append(Instance(obj.name, key, m, NO_CARDS))
            todo.setdefault(key, obj)
            continue
        ckey = cards_hash(obj, key, settings, digests)
        instances.append(Instance(obj.name, key, m, ckey))
        todo.setdefault(key, obj)
        card_todo.setdefault(ckey, (obj, key))
    if problems:
        raise SceneBakeError(problems)
    for name, value in (("texel density", settings.texel_density), ("texel budget", settings.texel_budget)):
        if not (np.isfinite(value) and value > 0):
            raise SceneBakeError([("scene", f"{name} must be a positive number, got {value!r}")])

    def scene_points(obj):
        """The other objects' centres in obj's local space (geometry.orient_triangles: an
        inward-facing closed shell around some of them is a room seen from inside)."""
        others = np.array([c for n, c in centres if n != obj.name and c is not None])
        try:
            inv = np.linalg.inv(np.asarray(obj.matrix_world, np.float64))
        except np.linalg.LinAlgError:
            return None
        return others @ inv[:3, :3].T + inv[:3, 3] if len(others) else None

    # Winding fixes (geometry.orient_triangles), once per mesh for its SDF and its cards alike.
    orientations = {}

    def orientation(key, obj):
        if obj.two_sided:
            return None
        if key not in orientations:
            orientations[key] = orient_triangles(obj.vertices, obj.triangles,
                                                 inside_points=scene_points(obj))
        return orientations[key]

    meshes, reused = {}, 0
    old = previous.meshes if previous is not None else {}
    cost = {k: max(len(o.triangles), 1) ** 0.5 for k, o in todo.items() if k not in old}
    total, done = (sum(cost.values()) or 1.0) / SDF_SHARE, 0.0
    for key, obj in todo.items():
        if key in old:
            meshes[key], reused = old[key], reused + 1
            continue
        span = cost[key] / total

        def sub(f, done=done, span=span, name=obj.name):
            if progress:
                progress(done + span * f, name)

        sub(0.0)
        sdf = bake_mesh_sdf(obj.vertices, obj.triangles,
                            voxel_density=settings.voxel_density * sdf_scale(obj.matrix_world),
                            resolution_scale=obj.resolution_scale, two_sided=obj.two_sided,
                            max_resolution=settings.max_resolution,
                            inside_fraction=settings.inside_fraction, progress=sub,
                            orientation=orientation(key, obj))
        warnings.extend((obj.name, note) for note in sdf.orientation_notes)
        if sdf.clamped:
            warnings.append((obj.name, f"resolution {'x'.join(map(str, sdf.requested_resolution))} "
                             f"clamped to {'x'.join(map(str, sdf.mips[0].resolution))} voxels"))
        if sdf.dropped_degenerate:
            warnings.append((obj.name, f"{sdf.dropped_degenerate} zero-area faces ignored"))
        meshes[key] = sdf
        done += span
    cards = _bake_cards(card_todo, settings, previous, warnings,
                        lambda f, name: progress(done + (1.0 - done) * f, name) if progress else None,
                        orientation)
    atlas = build_atlas(cards)
    if progress:
        progress(1.0, "")
    return SceneBake(settings, meshes, instances, time.perf_counter() - start, reused, warnings,
                     cards, atlas)


def too_small_for_cards(obj, matrix, min_size: float) -> bool:
    """Whether an object gets no cards: its world bounds are under `min_size` on every axis
    and none of its materials emits (emitters keep theirs: their light is read from cards).
    Why: a card has at least 4x4 texels, so a scatter of 5,000 8-cm pebbles held 540
    surface-cache tiles (74 without them) and one F12 GI iteration relit them all: 77 s,
    30 s at min_card_size 0.1 (tools/odd_scenes.py dense_scatter). Lumen leaves such meshes out
    of its surface cache too (MeshCardsMinSize, 10 cm). Rays that hit one read the voxel
    lighting there (gi_trace_lib.glsl gi_trace_lit_from), the light around it, which misses most of
    the light pebbles bounce onto each other (tests/gpu/test_small_objects.py: a third of their
    indirect light): so it is off by default (0), a setting for scatters that must render fast."""
    if not min_size > 0:
        return False
    for mat in obj.materials or ():
        if mat.emission_strength and (mat.emission_texture is not None
                                      or max(map(float, mat.emission_color[:3])) > 0):
            return False
    b = _local_bounds(obj)
    if b is None:
        return False
    extent = np.abs(np.asarray(matrix, np.float64)[:3, :3]) @ (b[1] - b[0])
    return bool(np.isfinite(extent).all() and extent.max() < min_size)


def _local_bounds(obj):
    v = np.asarray(obj.vertices, np.float64).reshape(-1, 3)
    v = v[np.isfinite(v).all(axis=1)]
    return (v.min(axis=0), v.max(axis=0)) if len(v) else None


def _world_centre(obj):
    """World centre of an object's vertex bounds (None when it has none or cannot be placed)."""
    b = _local_bounds(obj)
    m = np.asarray(obj.matrix_world, np.float64)
    if b is None or m.shape != (4, 4) or not np.isfinite(m).all():
        return None
    return m[:3, :3] @ (0.5 * (b[0] + b[1])) + m[:3, 3]


def _faces_inward(obj) -> bool:
    """Negative total signed volume: some closed shell of the mesh faces inwards (a room seen
    from inside, or an inside-out object); only then can the scene around it change its bake."""
    v = np.asarray(obj.vertices, np.float64).reshape(-1, 3)
    t = np.asarray(obj.triangles, np.int64).reshape(-1, 3)
    if not len(t) or not np.isfinite(v).all():
        return False
    a, b, c = (v[t[:, k]] - v.mean(axis=0) for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) < 0.0


def _holds_others(obj, m, centres) -> bool:
    """Whether another object's centre lies in this object's world bounds (cheap: decides only
    whether the bake key must carry its context, see scene_points)."""
    b = _local_bounds(obj)
    others = [c for n, c in centres if n != obj.name and c is not None]
    if b is None or not others:
        return False
    corners = np.array([[x, y, z] for x in (b[0][0], b[1][0]) for y in (b[0][1], b[1][1])
                        for z in (b[0][2], b[1][2])])
    w = corners @ m[:3, :3].T + m[:3, 3]
    lo, hi = w.min(axis=0), w.max(axis=0)
    c = np.asarray(others)
    return bool(np.any(np.all((c >= lo) & (c <= hi), axis=1)))


def _bake_cards(todo: dict, settings: BakeSettings, previous, warnings, progress, orientation) -> dict:
    """Cards of every unique (mesh, materials, scale): place all, fit the texel budget, capture.
    todo: cards hash -> (object, SDF hash); orientation(SDF hash, object): its winding fixes."""
    old = previous.cards if previous is not None else {}
    out = {k: old[k] for k in todo if k in old}
    new = {}
    for key, (obj, mesh_key) in todo.items():
        if key in out:
            continue
        progress(0.3 * len(new) / max(len(todo), 1), obj.name)
        surface, attrs, notes = cardlib.prepare(obj.vertices, obj.triangles, obj.normals, obj.uvs,
                                                obj.material_ids, obj.materials,
                                                colors=obj.colors, two_sided=obj.two_sided,
                                                orientation=orientation(mesh_key, obj))
        warnings.extend((obj.name, n) for n in notes)
        placed = cardlib.place_cards(surface, max_cards=settings.max_cards)
        new[key] = (obj, surface, attrs, placed, settings.texel_density * world_scale(obj.matrix_world))
    kept = sum(mc.texels for mc in out.values())
    for _, _, _, placed, density in new.values():
        cardlib.set_resolution(placed, density)
    wanted = sum(c.resolution[0] * c.resolution[1] for *_, placed, _ in new.values() for c in placed)
    if wanted and kept + wanted > settings.texel_budget:
        room = max(settings.texel_budget - kept, 0)
        f = float(np.sqrt(room / wanted))
        for _ in range(60):      # rounding each side up can overshoot: shrink until it fits
            for _, _, _, placed, density in new.values():
                cardlib.set_resolution(placed, density * f)
            got = sum(c.resolution[0] * c.resolution[1] for *_, placed, _ in new.values() for c in placed)
            if got <= room:
                break
            f *= 0.97
        warnings.append(("scene", f"{kept + wanted:,} card texels exceed the budget of "
                                  f"{settings.texel_budget:,}: new cards scaled to {100 * f:.0f}% "
                                  f"resolution"))
        if got > room:
            warnings.append(("scene", f"even at 4x4 texels per card the cards need {kept + got:,} "
                                      f"texels; raise the texel budget"))
    for n, (key, (obj, surface, attrs, placed, _)) in enumerate(new.items()):
        progress(0.3 + 0.7 * n / len(new), obj.name)
        cardlib.capture(surface, placed, **attrs)
        out[key] = cardlib.finish(surface, placed, [])
    return out


__all__ = ["BakeSettings", "ObjectInput", "Instance", "SceneBake", "SceneBakeError", "BakeCancelled",
           "MeshSDF", "bake_scene", "mesh_hash", "sdf_scale", "__version__"]
