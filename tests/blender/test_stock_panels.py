"""With Lumen GI as the render engine, Blender's own panels an artist needs stay visible, and
Object > Visibility gets the Ray Visibility switches the engine honours."""
from blender_runner import blender  # noqa: F401  (fixture)

NEEDED = ["RENDER_PT_format", "RENDER_PT_output", "RENDER_PT_color_management", "DATA_PT_lens",
          "DATA_PT_camera", "DATA_PT_EEVEE_light", "EEVEE_MATERIAL_PT_surface",
          "EEVEE_MATERIAL_PT_context_material", "EEVEE_WORLD_PT_surface",
          "VIEWLAYER_PT_layer"]


def test_stock_panels_show_for_lumen_and_unregister_cleanly(blender):
    res = blender(f"""
        from types import SimpleNamespace
        names = {NEEDED!r}
        def compat(name):
            return 'LUMEN_GI' in getattr(getattr(bpy.types, name), 'COMPAT_ENGINES', set())
        ctx = SimpleNamespace(engine='LUMEN_GI', scene=bpy.context.scene)
        fmt_poll = bpy.types.RENDER_PT_format.poll(ctx)
        with_engine = {{n: compat(n) for n in names}}
        light_panels = sum(compat(n) for n in ('DATA_PT_light', 'DATA_PT_EEVEE_light'))
        eevee_only = compat('RENDER_PT_eevee_sampling')
        bpy.ops.mesh.primitive_cube_add()
        ray = bpy.types.OBJECT_PT_lumen_ray_visibility
        ray_poll = [ray.poll(SimpleNamespace(engine=e, object=bpy.context.object))
                    for e in ('LUMEN_GI', 'CYCLES')]
        bpy.ops.object.light_add(type='POINT')
        ray_poll.append(ray.poll(SimpleNamespace(engine='LUMEN_GI', object=bpy.context.object)))
        bpy.ops.object.camera_add()
        ray_poll.append(ray.poll(SimpleNamespace(engine='LUMEN_GI', object=bpy.context.object)))
        ray_parent = (ray.bl_parent_id, compat(ray.bl_parent_id))
        addon.unregister()
        after = [n for n in names if compat(n)]
        emit(with_engine=with_engine, fmt_poll=fmt_poll, light_panels=light_panels,
             eevee_only=eevee_only, after=after, ray_poll=ray_poll, ray_parent=ray_parent,
             ray_gone=not hasattr(bpy.types, 'OBJECT_PT_lumen_ray_visibility'))
    """)
    r = res.result
    missing = [n for n, ok in r["with_engine"].items() if not ok]
    assert not missing, f"hidden with Lumen GI: {missing}"
    assert r["fmt_poll"], "Output > Format does not poll for Lumen GI"
    assert r["light_panels"] == 1, "exactly one Light panel (EEVEE's: colour, power, radius)"
    assert not r["eevee_only"], "EEVEE's own render settings must not show for Lumen GI"
    assert r["after"] == [], f"unregister left LUMEN_GI in {r['after']}"
    # Object > Visibility > Ray Visibility (Camera, Diffuse, Shadow) for Lumen GI alone, under
    # Blender's Visibility panel, which shows with Lumen GI
    assert r["ray_poll"] == [True, False, True, False]     # a mesh, not Cycles; a light; no camera
    assert r["ray_parent"] == ["OBJECT_PT_visibility", True]
    assert r["ray_gone"]
