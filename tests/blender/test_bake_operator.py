"""`lumen.bake` and `lumen.export_cache` on real scenes, in a fresh Blender per test."""
from blender_runner import blender  # noqa: F401  (fixture)


def test_bake_shares_instances_uses_evaluated_meshes_and_writes_cache(blender, tmp_path):
    cache = tmp_path / "cache"
    res = blender(f"""
        scene = empty_scene(cache_dir={str(cache)!r})
        cube("Box")
        ball = sphere("Ball", location=(2, 0, 0), subdivide=1)
        dup = link(ball.copy()); dup.name = "Ball.dup"; dup.location.x = 3      # linked duplicate
        raw = link(ball.copy()); raw.name = "Ball.raw"; raw.modifiers.clear()   # same mesh, no modifier
        props = bpy.data.collections.new("Props")                              # not in the scene
        bpy.ops.mesh.primitive_cone_add(vertices=8, location=(0, 0, 1))
        cone = bpy.context.object; cone.name = "Cone"
        for c in list(cone.users_collection):
            c.objects.unlink(cone)
        props.objects.link(cone)
        collection_instancer("Props.A", props, location=(0, 3, 0))
        collection_instancer("Props.B", props, location=(0, 6, 0))
        hidden = loose_vertices("Hidden")     # would fail the bake if it were not skipped
        hidden.hide_set(True)

        from lumen_gi.operators.extract import extract_objects
        objects = {{o.name: o for o in extract_objects(bpy.context.evaluated_depsgraph_get())}}
        loop_total = np.empty(len(ball.data.polygons), np.int32)
        ball.data.polygons.foreach_get("loop_total", loop_total)

        result, error = bake()
        from lumen_gi.lumen_addon.cache import read_cache
        back = read_cache({str(cache)!r})
        emit(result=result, error=error, stats=scene_stats(scene),
             names=sorted(objects),
             tris={{n: len(o.triangles) for n, o in objects.items()}},
             subdivided_expected=int(2 * loop_total.sum()),
             same_arrays=objects["Ball.raw"].vertices is objects["Ball.dup"].vertices,
             instance_pos={{n: o.matrix_world[:3, 3].tolist() for n, o in objects.items()}},
             cache_instances={{i.name: i.mesh for i in back.instances}},
             cache_stats=back.stats())
    """)
    r = res.result
    assert r["error"] is None and r["result"] == ["FINISHED"]
    assert r["names"] == ["Ball", "Ball.dup", "Ball.raw", "Box", "Props.A/Cone.001",
                          "Props.B/Cone.001"]
    # The evaluated mesh is baked: Subdivision level 1 turns each n-gon into n quads.
    assert r["tris"]["Ball"] == r["tris"]["Ball.dup"] == r["subdivided_expected"] == 224
    assert r["tris"]["Ball.raw"] == 48 and r["tris"]["Box"] == 12
    assert r["instance_pos"]["Props.B/Cone.001"] == [0.0, 6.0, 1.0]

    inst = r["cache_instances"]
    assert set(inst) == set(r["names"])
    assert inst["Ball"] == inst["Ball.dup"] != inst["Ball.raw"]
    assert inst["Props.A/Cone.001"] == inst["Props.B/Cone.001"]
    stats = r["stats"]
    assert stats["objects"] == 6
    assert stats["unique_meshes"] == 4 < stats["objects"]
    assert stats["bricks"] == r["cache_stats"]["bricks"] > 0
    assert stats["bytes"] == r["cache_stats"]["bytes"] > 0
    assert stats["seconds"] > 0
    assert stats["status"].startswith("Baked 6 objects") and str(cache) in stats["status"]


def test_geometry_nodes_instances_bake_once_with_their_own_matrices(blender, tmp_path):
    cache = tmp_path / "cache"
    res = blender(f"""
        scene = empty_scene(cache_dir={str(cache)!r})
        scatter = geometry_nodes_scatter("Scatter")
        scatter.lumen.resolution_scale = 0.5     # instances take their instancer's settings
        from lumen_gi.operators.extract import extract_objects
        objects = extract_objects(bpy.context.evaluated_depsgraph_get())
        result, error = bake()
        from lumen_gi.lumen_addon.cache import read_cache
        back = read_cache({str(cache)!r})
        emit(result=result, error=error,
             objects=[(o.name, len(o.triangles), o.matrix_world[:3, 3].tolist(), o.resolution_scale)
                      for o in objects],
             meshes={{i.name: i.mesh for i in back.instances}}, stats=scene_stats(scene))
    """)
    r = res.result
    assert r["result"] == ["FINISHED"], r["error"]
    plane, *instances = r["objects"]
    assert plane[:2] == ["Scatter", 2]
    assert len(instances) == 4
    assert {tuple(o[2]) for o in instances} == {(x, y, 0.0) for x in (-2.0, 2.0) for y in (-2.0, 2.0)}
    assert all(o[1] == 20 and o[0].startswith("Scatter/") and o[3] == 0.5 for o in instances)
    assert len({r["meshes"][o[0]] for o in instances}) == 1       # one bake for all four
    assert r["stats"]["objects"] == 5 and r["stats"]["unique_meshes"] == 2


def test_export_bakes_when_needed_and_rebake_reuses_unchanged_meshes(blender, tmp_path):
    cache, exp1, exp2 = tmp_path / "cache", tmp_path / "export1", tmp_path / "export2"
    res = blender(f"""
        from lumen_gi.lumen_addon.cache import read_cache
        scene = empty_scene(cache_dir={str(cache)!r})
        box = cube("Box")
        ball = sphere("Ball", location=(2, 0, 0))
        out = {{}}
        # No bake in memory yet: export bakes first, then writes only the export folder.
        out["export1"] = bake(bpy.ops.lumen.export_cache, filepath={str(exp1)!r})
        out["export1_objects"] = scene.lumen.last_bake.objects
        out["cache_after_export"] = (read_cache({str(exp1)!r}).stats()["objects"])
        out["bake1"] = bake(); out["reused1"] = scene.lumen.last_bake.reused
        files1 = snapshot({str(cache)!r})
        out["bake2"] = bake(); out["reused2"] = scene.lumen.last_bake.reused
        files2 = snapshot({str(cache)!r})
        out["same_arrays"] = sorted(k for k in files1 if k.endswith(".npz")) == \\
            sorted(k for k in files2 if k.endswith(".npz"))
        box.location.x = 5                      # a transform is not a mesh change
        out["bake3"] = bake(); out["reused3"] = scene.lumen.last_bake.reused
        ball.lumen.resolution_scale = 2.0       # this one must bake again
        out["bake4"] = bake(); out["reused4"] = scene.lumen.last_bake.reused
        out["export2"] = bake(bpy.ops.lumen.export_cache, filepath={str(exp2)!r})
        a, b = read_cache({str(cache)!r}), read_cache({str(exp2)!r})
        out["export_matches_cache"] = sorted(a.meshes) == sorted(b.meshes)
        out["box_x"] = [i.matrix_world[0][3] for i in b.instances if i.name == "Box"]
        out["status"] = scene.lumen.last_bake.status
        from lumen_gi.operators.bake_op import LAST_BAKES
        out["remembered"] = sorted(LAST_BAKES)
        empty_scene()                           # another file: its "Scene" is not this one
        out["forgotten"] = sorted(LAST_BAKES)
        emit(**out)

        # A reopened file has no bake in memory: the cache on disk seeds the reuse.
        scene = empty_scene(cache_dir={str(cache)!r})
        cube("Box"); sphere("Ball", location=(2, 0, 0)); cube("New", size=0.5, location=(0, 3, 0))
        emit(reopened=bake(), reused_from_disk=scene.lumen.last_bake.reused,
             unique_after_reopen=scene.lumen.last_bake.unique_meshes)
    """)
    r = res.result
    for key in ("export1", "bake1", "bake2", "bake3", "bake4", "export2"):
        assert r[key] == [["FINISHED"], None], key
    assert r["export1_objects"] == 2 and r["cache_after_export"] == 2
    assert r["reused1"] == 2 and r["reused2"] == 2 and r["reused3"] == 2 and r["reused4"] == 1
    assert r["same_arrays"]
    assert r["export_matches_cache"]
    assert r["box_x"] == [5.0]
    assert r["status"].startswith("Exported 2 objects") and str(exp2) in r["status"]
    assert r["remembered"] == ["Scene"] and r["forgotten"] == []
    # Box is unchanged, New is new, and Ball's resolution scale is back to 1: the cache on disk
    # holds the scale-2 Ball only, so 1 of 3 meshes is reused.
    assert r["reopened"] == [["FINISHED"], None]
    assert r["unique_after_reopen"] == 3 and r["reused_from_disk"] == 1


def test_relative_cache_dir_goes_to_temp_when_unsaved_and_next_to_saved_blend(blender, tmp_path):
    res = blender(f"""
        import os, tempfile
        scene = empty_scene()             # cache_dir stays "//lumen_cache/{{scene}}"
        cube("Box")
        first = bake()
        temp_manifest = os.path.join(tempfile.gettempdir(), "lumen_gi", "lumen_cache", "Scene",
                                     "manifest.json")
        bpy.ops.wm.save_as_mainfile(filepath={str(tmp_path / "scene.blend")!r})
        second = bake()
        emit(first=first, second=second, temp=os.path.isfile(temp_manifest),
             temp_dir=tempfile.gettempdir())
    """)
    r = res.result
    assert r["first"] == [["FINISHED"], None] and r["second"] == [["FINISHED"], None]
    assert r["temp"] and r["temp_dir"] == str(tmp_path / "tmp")
    assert (tmp_path / "lumen_cache" / "Scene" / "manifest.json").is_file()


def test_worker_job_bakes_and_cancels_without_bpy(blender):
    """The modal path's worker: plain arrays in, SceneBake or BakeCancelled out."""
    res = blender("""
        from lumen_gi.operators.bake_op import _Job, settings_from
        from lumen_gi.operators.extract import extract_objects
        from lumen_gi.lumen_addon.bake import BakeCancelled
        scene = empty_scene()
        cube("Box"); sphere("Ball", location=(2, 0, 0))
        objects = extract_objects(bpy.context.evaluated_depsgraph_get())
        ok = _Job(scene.name, objects, settings_from(scene), None)
        ok.thread.start(); ok.thread.join(60)
        stop = _Job(scene.name, objects, settings_from(scene), None)
        stop.cancel.set()
        stop.thread.start(); stop.thread.join(60)
        emit(ok=ok.result is not None and ok.error is None, fraction=ok.fraction,
             cancelled=isinstance(stop.error, BakeCancelled), stop_result=stop.result is None)
    """)
    r = res.result
    assert r["ok"] and r["fraction"] == 1.0
    assert r["cancelled"] and r["stop_result"]


def test_panel_draws_existing_properties_and_operators(blender):
    """Headless Blender has no UI to draw into; a recording layout (blender_scenes.draw_panels)
    checks every name the panels use against the real registered RNA (catches typos that would
    blank a panel). The sidebar holds the bake, its settings, the object's and the last bake's as
    sub-panels; the engine's settings are in Render Properties, shown with the engine chosen."""
    res = blender("""
        from lumen_gi.operators import panel
        scene = empty_scene()
        cube("Box")
        side = draw_panels(panel.SIDEBAR_PANELS)
        render_eevee = draw_panels(panel.RENDER_PANELS)
        scene.render.engine = "LUMEN_GI"
        from lumen_gi.gpu_shaders.engine import MEMORY
        MEMORY[scene.name] = {"atlas": 100, "objects": 20, "cards_albedo": 10, "sky": 5,
                              "voxel_lighting": 7, "lpv_grid": 3}
        render = draw_panels(panel.RENDER_PANELS)
        side_gi = draw_panels(panel.SIDEBAR_PANELS)
        parents = {c.__name__: getattr(c, "bl_parent_id", "") for c in panel._CLASSES}
        registered = [n for n in parents if not hasattr(bpy.types, n)]
        emit(side=side, side_gi=side_gi, render_eevee=render_eevee, render=render,
             parents=parents, registered=registered,
             closed=sorted(c.__name__ for c in panel._CLASSES
                           if 'DEFAULT_CLOSED' in getattr(c, "bl_options", set())),
             category=sorted({c.bl_category for c in panel.SIDEBAR_PANELS}),
             region=sorted({c.bl_region_type for c in panel.SIDEBAR_PANELS}))
    """)
    r = res.result
    assert r["registered"] == [], f"not registered: {r['registered']}"
    assert r["category"] == ["Lumen"] and r["region"] == ["UI"]
    props = lambda log: [name for kind, name in log if kind in ("prop", "operator")]
    side = {k: props(v) for k, v in r["side"].items()}
    assert side == {"VIEW3D_PT_lumen": ["lumen.bake", "lumen.export_cache", "lumen.open_atlas"],
                    "VIEW3D_PT_lumen_bake": ["voxel_density", "max_resolution", "texel_density",
                                             "texel_budget", "min_card_size", "cache_dir"],
                    "VIEW3D_PT_lumen_object": ["resolution_scale", "two_sided"],
                    "VIEW3D_PT_lumen_last_bake": []}, side
    assert r["side_gi"] == r["side"]               # the engine's settings are not in the sidebar
    labels = [name for kind, name in r["side"]["VIEW3D_PT_lumen_last_bake"] if kind == "label"]
    for label in ("Cards", "Texels", "Coverage"):
        assert label in labels
    bake_label = [n for k, n in r["side"]["VIEW3D_PT_lumen_bake"] if k == "label"]
    assert bake_label == ["= 2048 x 2048 atlas, ~420 MB of GPU memory"]
    assert r["render_eevee"] == {}                  # another engine: no Lumen GI panels
    render = {k: props(v) for k, v in r["render"].items()}
    assert render == {"RENDER_PT_lumen_gi": [],
                      "RENDER_PT_lumen_gi_viewport": ["viewport_quality", "viewport_split", "cache_texels_per_frame",
                                                      "preview_pixel_size"],
                      "RENDER_PT_lumen_gi_render": ["render_quality", "bounces", "converge_bounces",
                                                    "render_frames", "noise_threshold",
                                                    "seed", "aa_samples"],
                      "RENDER_PT_lumen_gi_method": ["gi_method"],
                      "RENDER_PT_lumen_gi_lumen": ["gi_gather", "screen_trace", "screen_hit",
                                                   "adaptive_probes", "probe_importance",
                                                   "radiance_cache"],  # default method
                      "RENDER_PT_lumen_gi_debug": ["debug_view"]}, render
    memory = [n for k, n in r["render"]["RENDER_PT_lumen_gi_debug"] if k == "label"]
    assert memory == ["GPU Mesh SDFs", "120 B", "GPU Cards", "10 B", "GPU Sky", "5 B",
                      "GPU Voxel lighting", "7 B", "GPU LPV", "3 B", "GPU Total", "145 B"], memory
    p = r["parents"]
    assert {n for n, parent in p.items() if n.startswith("VIEW3D") and parent} == {
        "VIEW3D_PT_lumen_bake", "VIEW3D_PT_lumen_object", "VIEW3D_PT_lumen_last_bake"}
    method_panel = "RENDER_PT_lumen_gi_method"
    assert p["RENDER_PT_lumen_gi_ssgi"] == p["RENDER_PT_lumen_gi_rsm"] == method_panel
    assert r["closed"] == ["RENDER_PT_lumen_gi_debug"]


def test_paths_starting_with_tilde_mean_the_home_folder(blender, tmp_path):
    """export_cache(filepath="~/x") and a cache folder "~/y" write under $HOME, never into a
    folder literally named "~"."""
    home = tmp_path / "home"
    home.mkdir()
    res = blender(f"""
        import os
        scene = empty_scene(cache_dir="~/lumen_tilde_cache")
        cube("Box")
        out = dict(bake=bake(), export=bake(bpy.ops.lumen.export_cache, filepath="~/lumen_tilde_export"))
        emit(literal=os.path.exists("~"), **out)
    """, env={"HOME": str(home)})
    r = res.result
    assert r["bake"] == r["export"] == [["FINISHED"], None], r
    assert (home / "lumen_tilde_cache" / "manifest.json").is_file()
    assert (home / "lumen_tilde_export" / "manifest.json").is_file()
    assert not r["literal"], "a folder named '~' was made in the working directory"


def test_only_esc_cancels_a_running_bake(blender):
    """A right-click anywhere used to cancel a running bake; only Esc does now."""
    res = blender("""
        from types import SimpleNamespace as E
        from lumen_gi.operators.bake_op import cancels
        emit(esc=cancels(E(type='ESC', value='PRESS')),
             esc_release=cancels(E(type='ESC', value='RELEASE')),
             right=cancels(E(type='RIGHTMOUSE', value='PRESS')),
             timer=cancels(E(type='TIMER', value='NOTHING')))
    """)
    assert res.result == {"esc": True, "esc_release": False, "right": False, "timer": False}
