"""Mesh cards end to end: `lumen.bake` records the card stats, the atlas in the cache carries the
materials' colours, and `lumen.open_atlas` shows its layers as Blender images."""
import json

import numpy as np

from blender_runner import blender  # noqa: F401  (fixture)


def test_bake_records_cards_and_open_atlas_loads_the_layers(blender, tmp_path):
    cache = tmp_path / "cache"
    res = blender(f"""
        import json
        from lumen_gi.lumen_addon.cache import read_cache
        scene = empty_scene(cache_dir={str(cache)!r})
        box = cube("Box")
        box.data.materials.append(principled("Red", base=(0.8, 0.1, 0.1)))
        last = scene.lumen.last_bake
        out = {{"bake": bake(), "cards": last.cards, "texels": last.texels,
                "coverage": last.coverage, "status": last.status}}
        back = read_cache({str(cache)!r})
        albedo, opacity = back.atlas.layers["albedo"], back.atlas.layers["opacity"]
        covered = opacity[..., 0] > 0.5
        out["albedo_mean"] = albedo[covered].mean(axis=0).tolist()
        out["stats"] = back.stats()

        out["manifest"] = json.loads(open({str(cache / "manifest.json")!r}).read())
        out["open"] = bake(bpy.ops.lumen.open_atlas)
        def atlas_images():
            return {{i.name: [list(i.size), i.colorspace_settings.name, i.filepath]
                     for i in bpy.data.images if i.name.startswith("Lumen Atlas ")}}
        out["images"] = atlas_images()
        # A new bake writes new content-named files; opening again reloads the same images.
        box.data.materials[0] = principled("Green", base=(0.1, 0.8, 0.1))
        out["bake2"] = bake()
        out["open2"] = bake(bpy.ops.lumen.open_atlas)
        out["images2"] = atlas_images()
        img = bpy.data.images["Lumen Atlas albedo"]
        px = np.empty(len(img.pixels), np.float32); img.pixels.foreach_get(px)
        px = px.reshape(img.size[1], img.size[0], -1)
        out["green_in_blender"] = px[..., :3][px[..., 1] > 0.5].mean(axis=0).tolist()
        emit(**out)
    """)
    r = res.result
    assert r["bake"] == [["FINISHED"], None], r
    assert r["cards"] > 0 and r["cards"] == r["stats"]["cards"]
    assert r["texels"] == r["stats"]["texels"] > 0
    assert r["coverage"] >= 0.99
    assert " cards" in r["status"]
    assert np.allclose(r["albedo_mean"], (0.8, 0.1, 0.1), atol=0.02)   # the material reached the atlas

    manifest = r["manifest"]
    layers = manifest["atlas"]["layers"]
    size = manifest["atlas"]["size"]
    assert r["open"] == [["FINISHED"], None]
    images = r["images"]
    assert set(images) == {f"Lumen Atlas {name}" for name in layers}
    assert {"albedo", "normal", "depth", "emissive", "opacity"} <= set(layers)
    for name, entry in layers.items():
        img_size, space, path = images[f"Lumen Atlas {name}"]
        assert img_size == size and path == str(cache / entry["file"])
        if name in ("normal", "depth", "opacity"):
            assert space == "Non-Color", (name, space)
    assert images["Lumen Atlas albedo_srgb"][1] == "sRGB"

    assert r["bake2"] == [["FINISHED"], None] and r["open2"] == [["FINISHED"], None]
    assert set(r["images2"]) == set(images)                 # reloaded, no "Lumen Atlas albedo.001"
    final = json.loads((cache / "manifest.json").read_text())["atlas"]["layers"]
    assert all(r["images2"][f"Lumen Atlas {n}"][2] == str(cache / e["file"]) for n, e in final.items())
    assert r["images2"]["Lumen Atlas albedo"][2] != images["Lumen Atlas albedo"][2]
    assert np.allclose(r["green_in_blender"], (0.1, 0.8, 0.1), atol=0.02)


def test_open_atlas_without_cache_or_atlas_names_the_folder(blender, tmp_path):
    empty, old = tmp_path / "nothing", tmp_path / "old"
    old.mkdir()
    (old / "manifest.json").write_text(json.dumps({"format": "lumen-gi-cache", "version": 1}))
    res = blender(f"""
        scene = empty_scene(cache_dir={str(empty)!r})
        missing = bake(bpy.ops.lumen.open_atlas)
        scene.lumen.bake.cache_dir = {str(old)!r}
        no_atlas = bake(bpy.ops.lumen.open_atlas)
        emit(missing=missing, no_atlas=no_atlas,
             images=[i.name for i in bpy.data.images if i.name.startswith("Lumen Atlas")])
    """)
    r = res.result
    assert r["missing"][0] is None and "no Lumen cache in" in r["missing"][1]
    assert str(empty) in r["missing"][1]
    assert r["no_atlas"][0] is None and "no surface-cache atlas" in r["no_atlas"][1]
    assert str(old) in r["no_atlas"][1]
    assert r["images"] == []


def test_texel_settings_reach_the_bake_and_the_budget_warns(blender, tmp_path):
    res = blender(f"""
        scene = empty_scene(cache_dir={str(tmp_path / 'cache')!r})
        cube("Box", size=2.0)
        scene.lumen.bake.texel_density = 10.0
        first = bake(); small = scene.lumen.last_bake.texels
        scene.lumen.bake.texel_density = 40.0
        second = bake(); large = scene.lumen.last_bake.texels
        scene.lumen.bake.texel_budget = 4096
        cube("Bigger", size=3.0, location=(4, 0, 0))    # new cards: they must fit the budget
        third = bake()
        from lumen_gi.operators.bake_op import settings_from
        s = settings_from(scene)
        emit(runs=[first, second, third], small=small, large=large,
             settings=[s.texel_density, s.texel_budget], status=scene.lumen.last_bake.status)
    """)
    r = res.result
    assert all(run == [["FINISHED"], None] for run in r["runs"]), r["runs"]
    assert r["settings"] == [40.0, 4096]
    assert r["large"] > 8 * r["small"]                   # 4x the density: about 16x the texels
    assert "exceed the budget" in res.stdout and "1 bake warning" in r["status"]
