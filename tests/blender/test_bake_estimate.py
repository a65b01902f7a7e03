"""A memory and time estimate before a bake (lumen_addon/estimate.py, bake_op.bake_estimate):
shown in the N-panel, and a large bake warns before it starts (headless: a WARNING report; the
UI's invoke asks for confirmation, which needs a window and is not run here)."""
from blender_runner import blender  # noqa: F401  (fixture)


def test_estimate_counts_what_the_bake_extracts_and_warns_when_large(blender):
    res = blender("""
        import demo
        from lumen_gi.lumen_addon import estimate
        from lumen_gi.operators import bake_op
        from lumen_gi.operators.extract import extract_scene
        from lumen_gi.operators.panel import draw_estimate

        scene = demo.build_demo_scene()
        scene.lumen.bake.voxel_density = 6.0
        dg = bpy.context.evaluated_depsgraph_get()
        est = bake_op.bake_estimate(scene, dg)
        objects, _ = extract_scene(dg)
        unique = {id(o.triangles): len(o.triangles) for o in objects}   # instances share arrays

        labels = []
        class Layout:
            def label(self, **k): labels.append((k.get("text"), k.get("icon")))
        ctx = type("C", (), {"scene": scene, "view_layer": bpy.context.view_layer})()
        draw_estimate(Layout(), ctx)

        small = dict(large=est.large, triangles=est.triangles, extracted=sum(unique.values()),
                     text=est.text(), labels=labels)
        small["bake"] = bake()

        estimate.LARGE_SECONDS = 0.0      # any bake is 'large' now: the report says so first
        small["forced"] = bake()

        estimate.LARGE_SECONDS = 20.0
        big = sphere("Big", (0.0, 0.0, 3.0), subdivide=7)    # 917,504 triangles
        est = bake_op.bake_estimate(scene, bpy.context.evaluated_depsgraph_get())
        emit(small=small, big=dict(large=est.large, triangles=est.triangles, text=est.text(),
                                   gb=est.bytes / 1e9, seconds=est.seconds))
    """, timeout=300)
    r = res.result
    small, big = r["small"], r["big"]
    assert small["triangles"] == small["extracted"] > 0, small     # counts only, same totals
    assert not small["large"] and small["bake"] == [["FINISHED"], None], small
    assert small["labels"] == [[f"Bake: {small['text']}", "TIME"]], small["labels"]
    assert small["text"].startswith("~") and " MB, " in small["text"], small["text"]
    assert small["forced"] == [["FINISHED"], None]                   # warned, then baked
    warned = [line for line in res.stdout.splitlines() if line.startswith("Warning: Large bake")]
    assert len(warned) == 1 and "estimated" in warned[0], warned
    # a million triangles: about a gigabyte, so the bake asks first
    assert big["triangles"] - small["triangles"] == 917504 and big["large"], big
    assert 0.8 < big["gb"] < 2.5 and big["text"].startswith("~1."), big


def test_estimate_keeps_an_emitters_cards_under_min_card_size(blender):
    """Min Card Size leaves small meshes without cards, but not emitters (bake.too_small_for_cards):
    the estimate counts an emitting 5 cm cube's card texels and not a plain one's."""
    res = blender("""
        from lumen_gi.operators import bake_op

        scene = empty_scene(voxel_density=10.0, cache_dir="est")
        texels = {}
        for name, mat in (("Plain", principled("Plain")),
                          ("Ember", principled("Ember", emission=(1.0, 0.5, 0.2), strength=3.0))):
            bpy.ops.mesh.primitive_cube_add(size=0.05, location=(len(texels), 0.0, 0.0))
            bpy.context.object.name = name
            bpy.context.object.data.materials.append(mat)
            for size in (0.0, 0.1):
                scene.lumen.bake.min_card_size = size
                est = bake_op.bake_estimate(scene, bpy.context.evaluated_depsgraph_get())
                texels[f"{name}_{size}"] = est.texels
        emit(**texels)
    """, timeout=300)
    t = res.result
    assert t["Plain_0.0"] > 0 and t["Plain_0.1"] == 0, t        # the plain cube: no cards
    # with the emitter added, its cards stay under Min Card Size (the plain one's do not)
    assert t["Ember_0.1"] > 0 and t["Ember_0.0"] - t["Ember_0.1"] == t["Plain_0.0"], t
