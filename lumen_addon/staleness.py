"""What the scene holds that its bake does not: objects added or edited since the bake.

The engine traces the bake. An object deleted since is parked by the engine (it leaves the SDF
scene); one added or edited is drawn but casts and bounces what the bake holds for it (nothing,
or its old shape and colours) until the next bake, so the user must be told. An object is
*changed* when its name is not among the bake's instances (added, renamed) or its mesh content
hash or cards hash (geometry, two-sided, resolution scale, normals, UVs, materials and their
textures: bake.mesh_hash, bake.cards_hash) differs from its instance's. Moving, rotating or
scaling an object is not a change (the engine places the baked mesh where the object is).

Hashing every mesh every frame would cost more than the rest of a still frame's CPU work, so
`StaleCheck` remembers each object's verdict with a cheap signature (array sizes, two-sided,
resolution scale, material names) and hashes an object again only when its signature changed or
the caller marked it (the viewport marks what depsgraph.updates names). A new bake forgets
every verdict.
"""
from __future__ import annotations

import dataclasses

from .bake import NO_CARDS, cards_hash, context_key, mesh_hash, too_small_for_cards


def _signature(obj) -> tuple:
    """Cheap facts that most edits change (not all: a moved vertex keeps them)."""
    return (len(obj.vertices), len(obj.triangles), bool(obj.two_sided),
            float(obj.resolution_scale), obj.uvs is None,
            tuple(getattr(m, "name", "") for m in obj.materials))


def differs(obj, inst, settings, digests=None) -> bool:
    """Whether `obj` (ObjectInput) bakes differently from its baked instance `inst`, with the
    bake's settings. The SDF and the cards are hashed at the instance's baked scale: scaling an
    object changes its voxel and texel density (bake.sdf_scale), not what it is."""
    placed = dataclasses.replace(obj, matrix_world=inst.matrix_world)
    key = mesh_hash(placed, settings)
    if inst.mesh not in (key, context_key(key)):
        return True
    if too_small_for_cards(placed, inst.matrix_world, settings.min_card_size):
        return inst.cards != NO_CARDS
    return cards_hash(placed, inst.mesh, settings, digests) != inst.cards


def name_parts(name: str) -> set:
    """The outliner names an extracted object's name is made of: itself, and for instances
    ('instancer/source.001') the instancer and the source."""
    if "/" not in name:
        return {name}
    parent, label = name.split("/", 1)
    return {name, parent, label.rsplit(".", 1)[0]}


class StaleCheck:
    """Verdicts remembered between frames (one per engine instance, as its GPU state)."""

    def __init__(self):
        self.bake = None          # the bake the verdicts were made against
        self.verdicts = {}        # object name -> (signature, changed)
        self.dirty = set()        # names marked since the last check
        self.dirty_materials = set()
        self.dirty_textures = False
        self.hashed = 0           # objects hashed by the last check (tests, the cost)
        self.last = []            # the last check's answer

    def pending(self) -> bool:
        """Whether marks wait for the next check (the caller may skip a check otherwise when
        the objects did not change)."""
        return bool(self.dirty or self.dirty_materials or self.dirty_textures)

    def unchanged(self) -> list:
        """The last answer again, for a frame whose objects the caller knows did not change
        (same instances, no mesh re-read, same bake, nothing marked): nothing is hashed."""
        self.hashed = 0
        return self.last

    def mark(self, names=(), materials=(), textures=False):
        """Objects (outliner names), materials (names) or any image texture edited since the
        last check: the objects they concern are hashed again."""
        self.dirty.update(names)
        self.dirty_materials.update(materials)
        self.dirty_textures = self.dirty_textures or bool(textures)

    def _marked(self, obj) -> bool:
        if self.dirty and name_parts(obj.name) & self.dirty:
            return True
        if self.dirty_materials and any(getattr(m, "name", None) in self.dirty_materials
                                        for m in obj.materials):
            return True
        return self.dirty_textures and any(
            getattr(m, "base_color_texture", None) is not None
            or getattr(m, "emission_texture", None) is not None for m in obj.materials)

    def changed(self, bake, objects, skip=()) -> list:
        """Names of `objects` (ObjectInputs of the current scene) that the bake does not hold as
        they are, in their order. `skip`: names (or their instancers/sources) whose geometry
        cannot be judged here (F12 evaluates modifiers at render settings, the bake at
        viewport settings): only their presence counts."""
        if bake is not self.bake:
            self.bake, self.verdicts = bake, {}
        baked = {inst.name: inst for inst in bake.instances}
        skip = set(skip)
        out, verdicts, digests = [], {}, {}
        self.hashed = 0
        for obj in objects:                       # a loop over objects, not their elements
            inst = baked.get(obj.name)
            if inst is None:
                out.append(obj.name)
                continue
            if skip and name_parts(obj.name) & skip:
                continue
            sig = _signature(obj)
            old = self.verdicts.get(obj.name)
            if old is not None and old[0] == sig and not self._marked(obj):
                stale = old[1]
            else:
                stale = differs(obj, inst, bake.settings, digests)
                self.hashed += 1
            verdicts[obj.name] = (sig, stale)
            if stale:
                out.append(obj.name)
        self.verdicts = verdicts
        self.dirty, self.dirty_materials, self.dirty_textures = set(), set(), False
        self.last = out
        return out


def summary(names, limit: int = 3, what: str = "changed since the bake") -> str:
    """'3 objects changed since the bake (Box, Ball, Cone)'; '' when none."""
    if not names:
        return ""
    shown = ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit
                                        else "")
    return f"{len(names)} object{'s' if len(names) != 1 else ''} {what} ({shown})"
