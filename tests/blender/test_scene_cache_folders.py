"""One cache folder per scene by default: baking scene B of a .blend never replaces scene A's
cache, and F12 of scene A in a reopened file renders A's bake (both scenes used to share
//lumen_cache, so A rendered B's SDFs after B was baked)."""
from blender_runner import blender  # noqa: F401  (fixture)

from lumen_addon.cache import folder_name

# Scene names with characters a folder name cannot carry as they are.
A, B = "Shot A", "Shot/B"


def test_each_scene_keeps_its_own_cache_and_f12_reads_it_after_reopening(blender, tmp_path):
    blend = tmp_path / "two scenes.blend"
    first = blender(f"""
        from lumen_gi.lumen_addon.cache import read_cache
        from lumen_gi.operators.bake_op import scene_cache_folder
        a = empty_scene()                      # cache_dir left at its default
        a.name = {A!r}
        cube("BoxA")
        aimed_camera((0.0, -4.0, 2.0))
        a.render.engine = "LUMEN_GI"
        a.lumen.engine.render_quality = "OFF"
        a.render.resolution_x = a.render.resolution_y = 32
        b = bpy.data.scenes.new({B!r})
        b.lumen.bake.voxel_density = 4.0
        ball = sphere("BallB", location=(0.0, 0.0, 1.0))
        for c in list(ball.users_collection):
            c.objects.unlink(ball)
        b.collection.objects.link(ball)
        bpy.ops.wm.save_as_mainfile(filepath={str(blend)!r})

        def bake_scene(scene):
            with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
                return bake()

        out = {{"default": a.lumen.bake.cache_dir, "bake_a": bake_scene(a)}}
        folder_a, folder_b = scene_cache_folder(a), scene_cache_folder(b)
        files_a = snapshot(folder_a)
        out["bake_b"] = bake_scene(b)
        out["a_untouched"] = snapshot(folder_a) == files_a
        out["folders"] = [str(folder_a), str(folder_b)]
        out["objects"] = [[i.name for i in read_cache(f).instances] for f in (folder_a, folder_b)]
        bpy.ops.wm.save_mainfile()
        emit(**out)
    """)
    r = first.result
    assert r["bake_a"] == r["bake_b"] == [["FINISHED"], None], r
    assert r["default"] == "//lumen_cache/{scene}"
    folder_a, folder_b = (tmp_path / "lumen_cache" / folder_name(A), tmp_path / "lumen_cache" / folder_name(B))
    assert r["folders"] == [str(folder_a), str(folder_b)]
    assert folder_a != folder_b and folder_b.parent == tmp_path / "lumen_cache"   # "/" made no subfolder
    assert r["objects"] == [["BoxA"], ["BallB"]]
    assert r["a_untouched"], "baking scene B changed scene A's cache"
    assert (folder_a / "manifest.json").is_file() and (folder_b / "manifest.json").is_file()

    # A new Blender: nothing in memory, F12 of scene A must read A's own folder.
    second = blender(f"""
        bpy.ops.wm.open_mainfile(filepath={str(blend)!r})
        from lumen_gi.gpu_shaders import engine
        from lumen_gi.operators.bake_op import LAST_BAKES
        a, b = bpy.data.scenes[{A!r}], bpy.data.scenes[{B!r}]
        out = {{"in_memory": sorted(LAST_BAKES)}}
        bpy.ops.render.render(scene=a.name)
        out["source"] = engine.LAST_RENDER.get("source")
        out["error"] = engine.LAST_RENDER.get("error")
        out["objects"] = [[i.name for i in engine.scene_bake(s)[0].instances] for s in (a, b)]
        emit(**out)
    """, timeout=300)
    r = second.result
    assert r["in_memory"] == []
    assert r["error"] is None, r["error"]
    assert r["source"] == str(folder_a)
    assert r["objects"] == [["BoxA"], ["BallB"]]
