"""Scenes of the GI quality benchmark (bench/quality.py), each built in code from an empty file.

Every scene is pure diffuse (Principled BSDF, Specular IOR Level 0, Roughness 1: a Lambert BSDF
in Cycles and EEVEE), walls and floors are separate axis-aligned boxes with real thickness (the
ground of `thin` too), and each has a camera. All numbers live in the dictionaries below.

    cornell  the Cornell box: 2 m interior, 10 cm walls, red left / green right / white others,
             two white boxes, a small square area light 10 cm under the ceiling (not seen
             by the camera), black world, camera looking in through the open front
    window   a closed 4 x 4 x 3 m room, 20 cm walls, albedo 0.7, one 1 x 1 m window in the +Y
             wall; lit only by a sun outside (black world) through the window onto the floor;
             camera inside seeing the sun patch and the indirectly lit walls
    thin     a closed 3 x 3 x 2.2 m room whose walls and roof are 1.5 cm thick (under one 5 cm
             SDF voxel at the default 20 voxels/m) on a 12 x 12 x 0.5 m ground, bright sun and
             bright uniform sky; the roof is invisible to camera rays (`visible_camera = False`,
             it still blocks light) and the camera looks down into the room from above: Cycles
             shows the interior black, anything lit there is leaked light
    yard     an open yard lit only by Blender's bundled courtyard.exr HDRI (World: Environment
             Texture -> Background, no light): a ground, a wall with a roofed porch whose
             shade the sky must leave darker, two boxes; camera outside looking at the porch
    glow     a room lit only by emission (black world, no light): one mesh of single-sided,
             zero-thickness quads facing in (an imported OBJ's walls, two materials), an
             emissive ceiling panel, a box; camera inside
    imported a room written as an OBJ file (one object, four materials by `usemtl`, single-sided
             quads facing in, an open front) and Stanford's bunny (../shared/meshes, a file no
             one here wrote; skipped without it), both brought in by Blender's own OBJ importer
             (bpy.ops.wm.obj_import), lit by an area light under the ceiling and the sky
    textured a floor and two walls whose Base Color is an Image Texture (a brick pattern PNG
             written at build time, sRGB), a sun and a uniform sky

`build(name)` replaces the current file with the scene and returns it (renamed to `name`).
`add_probe_volume(scene)` adds the EEVEE irradiance volume of PROBE_VOLUMES[scene name].
`CAMERA_HIDDEN` names the objects each scene hides from camera rays (`visible_camera = False`).
"""
from __future__ import annotations

import math

# Shared ----------------------------------------------------------------------------------------
SPECULAR_IOR_LEVEL = 0.0         # no specular layer: a Lambert BSDF
ROUGHNESS = 1.0

# cornell: interior x, y in [-1, 1], z in [0, 2]; open front at y = -1, camera at -y.
CORNELL = dict(
    inner=2.0,                                   # interior edge, m
    wall=0.1,                                    # wall / floor / ceiling thickness, m
    white=(0.73, 0.71, 0.68),
    red=(0.63, 0.065, 0.05),
    green=(0.14, 0.45, 0.091),
    light_size=0.5,                              # square area light, m
    light_power=60.0,                            # W (Blender's area light power)
    light_z=1.9,                                 # 10 cm (2 default voxels) under the ceiling,
                                                 # facing down (at 5 cm LUMEN_GI's SDF shadows
                                                 # still lose most of its direct light)
    # (name, centre xyz of the base, size xyz, rotation about z in degrees)
    boxes=(("ShortBox", (0.35, -0.3, 0.0), (0.6, 0.6, 0.6), -17.0),
           ("TallBox", (-0.35, 0.3, 0.0), (0.6, 0.6, 1.2), 17.0)),
    camera=(0.0, -3.9, 1.0), target=(0.0, 0.0, 1.0), lens=38.0,
)

# window: interior x, y in [-2, 2], z in [0, 3]; the window is in the +Y wall.
WINDOW = dict(
    inner=(4.0, 4.0, 3.0),
    wall=0.2,
    albedo=(0.7, 0.7, 0.7),
    window_x=(-0.5, 0.5),                        # opening in the +Y wall, m
    window_z=(1.2, 2.2),
    sun_strength=20.0,                           # W/m^2 (irradiance facing the sun): walls
                                                 # ~0.1, well above relMSE's 0.01 floor
    sun_elevation=35.0,                          # degrees above the horizon
    sun_azimuth=20.0,                            # degrees from -Y towards -X (light travel)
    sun_angle=0.0093,                            # angular diameter, rad (Blender's default)
    camera=(0.8, -1.8, 1.4), target=(-0.05, -0.25, 0.95), lens=16.0,
)

# thin: interior x, y in [-1.5, 1.5], z in [0, 2.2]; the ground's top is z = 0.
THIN = dict(
    inner=(3.0, 3.0, 2.2),
    wall=0.015,                                  # walls and roof: 1.5 cm, < 1 voxel (5 cm)
    wall_albedo=(0.7, 0.7, 0.7),
    wall_sink=0.05,                              # walls start this far inside the ground (sealed)
    ground=(12.0, 12.0, 0.5),                    # x, y, thickness
    ground_albedo=(0.5, 0.5, 0.5),
    sun_strength=4.0,
    sun_elevation=50.0,
    sun_azimuth=30.0,
    sun_angle=0.0093,
    sky=(0.8, 0.9, 1.0),                         # uniform world radiance (Background strength 1)
    camera=(3.2, -4.6, 7.4), target=(0.0, 0.1, 0.3), lens=32.0,
)

# yard: ground top at z = 0; a 6 m wall along +Y with a porch roof in front of it.
YARD = dict(
    hdri="courtyard.exr",                        # Blender's datafiles/studiolights/world
    strength=1.0,
    ground=(14.0, 14.0, 0.3), ground_albedo=(0.45, 0.42, 0.38),
    wall=((-3.0, 1.5, 0.0), (3.0, 1.8, 2.8)), wall_albedo=(0.75, 0.72, 0.68),
    roof=((-2.0, -0.5, 2.4), (2.0, 1.5, 2.5)), roof_albedo=(0.6, 0.3, 0.2),
    boxes=(("Crate", (-0.8, 0.5, 0.0), (0.7, 0.7, 0.7), 20.0, (0.3, 0.45, 0.7)),
           ("Block", (1.8, -1.2, 0.0), (0.8, 0.8, 1.2), -10.0, (0.7, 0.7, 0.7))),
    camera=(2.6, -6.5, 1.7), target=(0.0, 0.6, 1.0), lens=28.0,
)

# glow: interior x in [-2, 2], y in [-1.5, 1.5], z in [0, 2.6]; single-sided quads facing in.
GLOW = dict(
    inner=(4.0, 3.0, 2.6),
    wall_albedo=(0.7, 0.7, 0.7), floor_albedo=(0.55, 0.45, 0.35),
    panel=((-0.5, -0.4), (0.5, 0.4), 2.55),     # emissive quad under the ceiling, facing down
    panel_colour=(1.0, 0.9, 0.75), panel_strength=12.0,
    box=((0.6, 0.2, 0.0), (0.7, 0.7, 0.9), 25.0, (0.7, 0.7, 0.7)),
    camera=(-1.7, -1.3, 1.5), target=(0.6, 0.5, 0.8), lens=16.0,
)

# imported: interior x in [-2, 2], y in [-2, 2], z in [0, 2.8]; open at y = -2.
IMPORTED = dict(
    inner=(4.0, 4.0, 2.8),
    materials={"floor": (0.6, 0.55, 0.5), "walls": (0.75, 0.75, 0.75), "left": (0.7, 0.2, 0.15),
               "ceiling": (0.8, 0.8, 0.8)},
    mesh="stanford-bunny.obj", mesh_height=1.0, mesh_at=(0.3, 0.4, 0.0),
    mesh_albedo=(0.8, 0.75, 0.6),
    light_size=0.8, light_power=250.0, light_z=2.7,
    sky=(0.05, 0.06, 0.08),
    camera=(0.0, -5.2, 1.5), target=(0.0, 0.0, 1.1), lens=28.0,
)

# textured: a brick-patterned floor and back walls
TEXTURED = dict(
    floor=6.0, wall_h=2.5, wall_t=0.15,
    brick=(0.55, 0.22, 0.15), mortar=(0.75, 0.72, 0.68), bricks_per_m=(4.0, 8.0),
    image_size=256,
    sun_strength=4.0, sun_elevation=40.0, sun_azimuth=-35.0, sun_angle=0.0093,
    sky=(0.35, 0.45, 0.6),
    camera=(3.2, -3.6, 1.8), target=(-0.3, 0.6, 0.7), lens=24.0,
)

# EEVEE irradiance volumes: (centre, half size). Each reaches past the room's walls (10-20 cm
# beyond their outer faces): measured here, a volume fitted to the interior (or inset) bakes
# without error but adds no light to the render (a closed room lit by a point light: mean
# luminance unchanged to 4 digits); reaching past the walls, the same bake adds the bounce light.
PROBE_VOLUMES = {
    "cornell": ((0.0, 0.0, 1.0), (1.2, 1.2, 1.2)),
    "window": ((0.0, 0.0, 1.5), (2.4, 2.4, 1.8)),
    "thin": ((0.0, 0.0, 1.1), (1.7, 1.7, 1.3)),
    "yard": ((0.0, 0.0, 1.5), (4.0, 3.0, 1.7)),
    "glow": ((0.0, 0.0, 1.3), (2.1, 1.6, 1.4)),
    "imported": ((0.0, 0.0, 1.4), (2.1, 2.1, 1.5)),
    "textured": ((0.0, 0.0, 1.3), (3.1, 3.1, 1.4)),
}
PROBE_RESOLUTION = None          # None: Blender's default probe grid; else (x, y, z)

SCENES = ("cornell", "window", "thin", "yard", "glow", "imported", "textured")
# ../shared/meshes beside the checkout (LUMEN_SHARED_MESHES overrides; never copied into the repo)
SHARED_MESHES = __import__("pathlib").Path(__import__("os").environ.get(
    "LUMEN_SHARED_MESHES", __import__("pathlib").Path(__file__).resolve().parents[2] / "shared" / "meshes"))
CAMERA_HIDDEN = {"thin": ("roof",)}


# Helpers ---------------------------------------------------------------------------------------
def _new_file(name):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    return scene


def lambert(name, colour):
    """A Principled BSDF material that is a pure Lambert BSDF of albedo `colour`."""
    import bpy

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = SPECULAR_IOR_LEVEL
    bsdf.inputs["Roughness"].default_value = ROUGHNESS
    mat.diffuse_color = (*colour, 1.0)
    return mat


def box(scene, name, lo, hi, material, rotation_z=0.0):
    """An axis-aligned box object from corner `lo` to corner `hi` (world metres), rotated about
    the vertical axis through its centre by `rotation_z` degrees; 6 outward quads."""
    import bpy

    centre = [(a + b) / 2.0 for a, b in zip(lo, hi)]
    h = [(b - a) / 2.0 for a, b in zip(lo, hi)]
    verts = [(sx * h[0], sy * h[1], sz * h[2]) for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = centre
    obj.rotation_euler = (0.0, 0.0, math.radians(rotation_z))
    scene.collection.objects.link(obj)
    return obj


def _aim(obj, target):
    import mathutils

    obj.rotation_euler = (mathutils.Vector(target) - obj.location).to_track_quat(
        "-Z", "Y").to_euler()


def _camera(scene, location, target, lens):
    import bpy

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = location
    _aim(cam, target)
    cam.data.lens = lens
    cam.data.clip_start = 0.05
    cam.data.clip_end = 100.0
    scene.camera = cam
    return cam


def _world(scene, colour):
    import bpy

    world = bpy.data.worlds.new("World")
    world.color = colour
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (*colour, 1.0)
        bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    return world


def _sun(scene, strength, elevation, azimuth, angle):
    """A sun whose light travels down at `elevation` degrees, horizontally towards -Y turned by
    `azimuth` degrees towards -X."""
    import bpy
    import mathutils

    el, az = math.radians(elevation), math.radians(azimuth)
    travel = mathutils.Vector((-math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el),
                               -math.sin(el)))
    data = bpy.data.lights.new("Sun", 'SUN')
    data.energy = strength
    data.angle = angle
    obj = bpy.data.objects.new("Sun", data)
    obj.location = -5.0 * travel
    obj.rotation_euler = travel.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(obj)
    return obj


# Scenes ----------------------------------------------------------------------------------------
def build_cornell():
    import bpy

    c = CORNELL
    scene = _new_file("cornell")
    s, t = c["inner"] / 2.0, c["wall"]
    top = c["inner"]
    white, red, green = (lambert("White", c["white"]), lambert("Red", c["red"]),
                         lambert("Green", c["green"]))
    box(scene, "Floor", (-s - t, -s, -t), (s + t, s + t, 0.0), white)
    box(scene, "Ceiling", (-s - t, -s, top), (s + t, s + t, top + t), white)
    box(scene, "Back", (-s - t, s, -t), (s + t, s + t, top + t), white)
    box(scene, "Left", (-s - t, -s, -t), (-s, s + t, top + t), red)
    box(scene, "Right", (s, -s, -t), (s + t, s + t, top + t), green)
    for name, (x, y, z), (sx, sy, sz), rot in c["boxes"]:
        box(scene, name, (x - sx / 2, y - sy / 2, z), (x + sx / 2, y + sy / 2, z + sz), white, rot)
    data = bpy.data.lights.new("Light", 'AREA')
    data.shape = 'SQUARE'
    data.size = c["light_size"]
    data.energy = c["light_power"]
    light = bpy.data.objects.new("Light", data)
    light.location = (0.0, 0.0, c["light_z"])        # an area light faces -Z: down
    light.visible_camera = False                     # no engine but Cycles would show it
    scene.collection.objects.link(light)
    _world(scene, (0.0, 0.0, 0.0))
    _camera(scene, c["camera"], c["target"], c["lens"])
    return scene


def build_window():
    w = WINDOW
    scene = _new_file("window")
    (ix, iy, iz), t = w["inner"], w["wall"]
    x, y = ix / 2.0, iy / 2.0
    mat = lambert("Wall", w["albedo"])
    box(scene, "Floor", (-x - t, -y - t, -t), (x + t, y + t, 0.0), mat)
    box(scene, "Ceiling", (-x - t, -y - t, iz), (x + t, y + t, iz + t), mat)
    box(scene, "WallSouth", (-x - t, -y - t, 0.0), (x + t, -y, iz), mat)
    box(scene, "WallWest", (-x - t, -y, 0.0), (-x, y, iz), mat)
    box(scene, "WallEast", (x, -y, 0.0), (x + t, y, iz), mat)
    (wx0, wx1), (wz0, wz1) = w["window_x"], w["window_z"]
    # the +Y wall around its window: left, right, below, above
    box(scene, "WallNorthLeft", (-x - t, y, 0.0), (wx0, y + t, iz), mat)
    box(scene, "WallNorthRight", (wx1, y, 0.0), (x + t, y + t, iz), mat)
    box(scene, "WallNorthBelow", (wx0, y, 0.0), (wx1, y + t, wz0), mat)
    box(scene, "WallNorthAbove", (wx0, y, wz1), (wx1, y + t, iz), mat)
    _sun(scene, w["sun_strength"], w["sun_elevation"], w["sun_azimuth"], w["sun_angle"])
    _world(scene, (0.0, 0.0, 0.0))
    _camera(scene, w["camera"], w["target"], w["lens"])
    return scene


def build_thin():
    th = THIN
    scene = _new_file("thin")
    (ix, iy, iz), t = th["inner"], th["wall"]
    x, y = ix / 2.0, iy / 2.0
    gx, gy, gz = th["ground"]
    ground = lambert("Ground", th["ground_albedo"])
    wall = lambert("ThinWall", th["wall_albedo"])
    box(scene, "Ground", (-gx / 2, -gy / 2, -gz), (gx / 2, gy / 2, 0.0), ground)
    z0 = -th["wall_sink"]
    box(scene, "WallSouth", (-x - t, -y - t, z0), (x + t, -y, iz), wall)
    box(scene, "WallNorth", (-x - t, y, z0), (x + t, y + t, iz), wall)
    box(scene, "WallWest", (-x - t, -y, z0), (-x, y, iz), wall)
    box(scene, "WallEast", (x, -y, z0), (x + t, y, iz), wall)
    roof = box(scene, "roof", (-x - t, -y - t, iz), (x + t, y + t, iz + t), wall)
    roof.visible_camera = False           # blocks light, not seen: the camera looks inside
    _sun(scene, th["sun_strength"], th["sun_elevation"], th["sun_azimuth"], th["sun_angle"])
    _world(scene, th["sky"])
    _camera(scene, th["camera"], th["target"], th["lens"])
    return scene


def _hdri_world(scene, filename, strength):
    """An Environment Texture of one of Blender's bundled HDRIs into the Background."""
    import os

    import bpy

    folder = bpy.utils.system_resource('DATAFILES', path="studiolights/world")
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(os.path.join(folder, filename), check_existing=True)
    bg = tree.nodes["Background"]
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    scene.world = world
    return world


def build_yard():
    y = YARD
    scene = _new_file("yard")
    gx, gy, gz = y["ground"]
    box(scene, "Ground", (-gx / 2, -gy / 2, -gz), (gx / 2, gy / 2, 0.0),
        lambert("Ground", y["ground_albedo"]))
    box(scene, "Wall", *y["wall"], lambert("Wall", y["wall_albedo"]))
    box(scene, "PorchRoof", *y["roof"], lambert("Roof", y["roof_albedo"]))
    for name, (x, yy, z), (sx, sy, sz), rot, colour in y["boxes"]:
        box(scene, name, (x - sx / 2, yy - sy / 2, z), (x + sx / 2, yy + sy / 2, z + sz),
            lambert(name, colour), rot)
    _hdri_world(scene, y["hdri"], y["strength"])
    _camera(scene, y["camera"], y["target"], y["lens"])
    return scene


def build_glow():
    import bpy

    g = GLOW
    scene = _new_file("glow")
    (ix, iy, iz) = g["inner"]
    x, yy = ix / 2.0, iy / 2.0
    v = [(sx * x, sy * yy, z) for z in (0.0, iz) for sy in (-1, 1) for sx in (-1, 1)]
    # quads wound so that their normals face into the room; floor first (material 1)
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [tuple(reversed(f)) for f in faces]
    mesh = bpy.data.meshes.new("Room")
    mesh.from_pydata(v, [], faces)
    mesh.update()
    mesh.materials.append(lambert("RoomWalls", g["wall_albedo"]))
    mesh.materials.append(lambert("RoomFloor", g["floor_albedo"]))
    mesh.polygons[0].material_index = 1
    room = bpy.data.objects.new("Room", mesh)
    scene.collection.objects.link(room)
    (px0, py0), (px1, py1), pz = g["panel"]
    pmesh = bpy.data.meshes.new("Panel")
    pmesh.from_pydata([(px0, py0, pz), (px1, py0, pz), (px1, py1, pz), (px0, py1, pz)], [],
                      [(3, 2, 1, 0)])                 # facing down
    pmesh.update()
    glow = lambert("PanelGlow", (0.8, 0.8, 0.8))
    bsdf = glow.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Emission Color"].default_value = (*g["panel_colour"], 1.0)
    bsdf.inputs["Emission Strength"].default_value = g["panel_strength"]
    pmesh.materials.append(glow)
    panel = bpy.data.objects.new("Panel", pmesh)
    scene.collection.objects.link(panel)
    (bx, by, bz), (sx, sy, sz), rot, colour = g["box"]
    box(scene, "Box", (bx - sx / 2, by - sy / 2, bz), (bx + sx / 2, by + sy / 2, bz + sz),
        lambert("Box", colour), rot)
    _world(scene, (0.0, 0.0, 0.0))
    _camera(scene, g["camera"], g["target"], g["lens"])
    return scene


def _write_room_obj(path, inner, materials):
    """An OBJ + MTL of a room: quads facing in, one `usemtl` group per material, no front wall
    (what a modelling tool exports: single-sided, zero thickness, one object)."""
    ix, iy, iz = inner
    x, y = ix / 2.0, iy / 2.0
    v = [(-x, -y, 0), (x, -y, 0), (x, y, 0), (-x, y, 0),
         (-x, -y, iz), (x, -y, iz), (x, y, iz), (-x, y, iz)]
    # faces wound counter-clockwise seen from inside (OBJ indices from 1; OBJ's Y is up: the
    # importer's default forward/up axes turn it into Blender's Z up)
    faces = {"floor": [(1, 2, 3, 4)], "ceiling": [(5, 8, 7, 6)], "walls": [(4, 3, 7, 8), (2, 6, 7, 3)],
             "left": [(1, 4, 8, 5)]}
    mtl = path.with_suffix(".mtl")
    mtl.write_text("".join(f"newmtl {name}\nKd {r} {g} {b}\nKs 0 0 0\nillum 1\n\n"
                           for name, (r, g, b) in materials.items()))
    lines = [f"mtllib {mtl.name}", "o Room"]
    lines += [f"v {a:.6f} {c:.6f} {-b:.6f}" for a, b, c in v]      # Blender (x, y, z) -> OBJ (x, z, -y)
    for name, quads in faces.items():
        lines.append(f"usemtl {name}")
        lines += ["f " + " ".join(str(i) for i in q) for q in quads]
    path.write_text("\n".join(lines) + "\n")


def _as_lambert(obj):
    """The importer's Principled materials made pure Lambert, like every benchmark material."""
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or mat.node_tree is None:
            continue
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Specular IOR Level"].default_value = SPECULAR_IOR_LEVEL
            bsdf.inputs["Roughness"].default_value = ROUGHNESS
            bsdf.inputs["Metallic"].default_value = 0.0


def build_imported():
    import tempfile
    from pathlib import Path

    import bpy

    im = IMPORTED
    scene = _new_file("imported")
    folder = Path(tempfile.mkdtemp(prefix="lumen_bench_obj_"))
    room_path = folder / "room.obj"
    _write_room_obj(room_path, im["inner"], im["materials"])
    bpy.ops.wm.obj_import(filepath=str(room_path))
    for obj in bpy.context.selected_objects:
        _as_lambert(obj)
    mesh_path = SHARED_MESHES / im["mesh"]
    if not mesh_path.is_file():
        raise FileNotFoundError(f"{mesh_path} is missing (../shared/meshes beside the checkout)")
    bpy.ops.wm.obj_import(filepath=str(mesh_path))
    for obj in bpy.context.selected_objects:
        dims = max(obj.dimensions)
        obj.scale = [im["mesh_height"] / max(dims, 1e-9)] * 3
        bpy.context.view_layer.update()
        lo = min((obj.matrix_world @ __import__("mathutils").Vector(c)).z for c in obj.bound_box)
        obj.location = (im["mesh_at"][0], im["mesh_at"][1], obj.location.z - lo)
        obj.data.materials.clear()
        obj.data.materials.append(lambert("Bunny", im["mesh_albedo"]))
    data = bpy.data.lights.new("Light", 'AREA')
    data.shape = 'SQUARE'
    data.size = im["light_size"]
    data.energy = im["light_power"]
    light = bpy.data.objects.new("Light", data)
    light.location = (0.0, 0.0, im["light_z"])
    light.visible_camera = False
    scene.collection.objects.link(light)
    _world(scene, im["sky"])
    _camera(scene, im["camera"], im["target"], im["lens"])
    return scene


def _brick_png(path, size, brick, mortar, rows):
    """A brick pattern (sRGB PNG): `rows` courses, half-brick offset, mortar lines."""
    import numpy as np
    import OpenImageIO as oiio

    yy, xx = np.mgrid[0:size, 0:size] / size
    course = np.floor(yy * rows)
    u = (xx * rows / 2 + 0.5 * (course % 2)) % 1.0
    v = (yy * rows) % 1.0
    is_mortar = (u < 0.04) | (v < 0.08)
    rng = np.random.default_rng(3)
    tint = 0.85 + 0.3 * rng.random((rows, rows))[course.astype(int) % rows,
                                                   np.floor(xx * rows / 2 + 0.5 * (course % 2)).astype(int) % rows]
    lin = np.where(is_mortar[..., None], mortar, np.asarray(brick) * tint[..., None])
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(size, size, 3, "uint8"))
    out.write_image(np.clip(np.round(srgb * 255), 0, 255).astype(np.uint8))
    out.close()


def _textured(name, image):
    mat = lambert(name, (0.8, 0.8, 0.8))
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tree.links.new(tex.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return mat


def build_textured():
    import tempfile
    from pathlib import Path

    import bpy

    t = TEXTURED
    scene = _new_file("textured")
    png = Path(tempfile.mkdtemp(prefix="lumen_bench_tex_")) / "bricks.png"
    _brick_png(png, t["image_size"], t["brick"], t["mortar"], 8)
    image = bpy.data.images.load(str(png))
    image.pack()                                     # the scene no longer needs the temp file
    mat = _textured("Bricks", image)
    f, h, w = t["floor"] / 2.0, t["wall_h"], t["wall_t"]
    floor = box(scene, "Floor", (-f, -f, -0.2), (f, f, 0.0), mat)
    back = box(scene, "BackWall", (-f, f - w, 0.0), (f, f, h), mat)
    side = box(scene, "SideWall", (-f, -f, 0.0), (-f + w, f - w, h), mat)
    for obj in (floor, back, side):
        _box_uvs(obj, t["bricks_per_m"][0] / 8.0)
    _sun(scene, t["sun_strength"], t["sun_elevation"], t["sun_azimuth"], t["sun_angle"])
    _world(scene, t["sky"])
    _camera(scene, t["camera"], t["target"], t["lens"])
    return scene


def _box_uvs(obj, repeats_per_m):
    """Box-projected UVs in world metres (each face takes the two axes it spans)."""
    import numpy as np

    mesh = obj.data
    uv = mesh.uv_layers.new(name="UVMap")
    m = np.array(obj.matrix_world)
    co = np.array([m[:3, :3] @ v.co + m[:3, 3] for v in mesh.vertices])
    for poly in mesh.polygons:
        axis = int(np.argmax(np.abs(np.array(poly.normal))))
        keep = [a for a in range(3) if a != axis]
        for li in poly.loop_indices:
            p = co[mesh.loops[li].vertex_index]
            uv.data[li].uv = (p[keep[0]] * repeats_per_m, p[keep[1]] * repeats_per_m)


BUILDERS = {"cornell": build_cornell, "window": build_window, "thin": build_thin,
            "yard": build_yard, "glow": build_glow, "imported": build_imported,
            "textured": build_textured}


def build(name):
    """Replace the current file with scene `name` (one of SCENES) and return it."""
    if name not in BUILDERS:
        raise KeyError(f"unknown scene {name!r}; known: {', '.join(SCENES)}")
    return BUILDERS[name]()


def add_probe_volume(scene, resolution=PROBE_RESOLUTION):
    """The EEVEE irradiance volume (light probe volume object) of PROBE_VOLUMES[scene.name]:
    the probe's unit cube scaled to the half size. Returns the object."""
    import bpy

    centre, half = PROBE_VOLUMES[scene.name]
    data = bpy.data.lightprobes.new("IrradianceVolume", 'VOLUME')
    if resolution is not None:
        data.resolution_x, data.resolution_y, data.resolution_z = resolution
    obj = bpy.data.objects.new("IrradianceVolume", data)
    obj.location = centre
    obj.scale = half
    scene.collection.objects.link(obj)
    return obj
