#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "probe_occlusion_lib.glsl"
/* Screen probes, how far each uniform probe's lifted end sees along its own surface: the
 * occlusion map screen_probe_integrate reads instead of a wall test (an SDF trace) per pixel
 * and probe (probe_occlusion_lib.glsl has the layout). One invocation per texel: texels 0-3 of a
 * probe trace 4 azimuths each (gi_trace_mesh with the thin-wall rule, from the probe's end
 * lifted GI_LIFT_VOXELS of its object's voxel, along its tangent plane, as far as `reach`: 1.05x
 * the farthest of its 8 grid neighbours plus a voxel, beyond which no pixel interpolating it
 * lies); texel 4 holds (voxel, the field at the lifted end, reach, 1). An adaptive probe and an
 * empty slot get no map (texel 4 w = 0). A lifted end within a surface's shell (a floor's probe
 * beside a sphere) starts as gi_trace_mesh's rays do: it only hits what it comes closer to.
 * Why: among 1,000 spheres on a floor the per-pixel tests were most of integrate, the viewport's
 * largest pass; a probe's 16 rays stand for the 4 x 16 x 16 tests of the pixels around it, and
 * the map is traced once per placement (the split's redraws keep it).
 * Inputs: probe_info, probe_normal, the mesh SDFs; uniform_grid. Output out_image (RGBA32F,
 * PROBE_OCC_TEXELS texels a probe across). */
void main()
{
  ivec2 id = ivec2(gl_GlobalInvocationID.xy);
  ivec2 pr = ivec2(id.x / PROBE_OCC_TEXELS, id.y);
  int part = id.x % PROBE_OCC_TEXELS;
  ivec2 size = textureSize(probe_info, 0);
  if (pr.x >= size.x || pr.y >= size.y) {
    return;
  }
  vec4 info = texelFetch(probe_info, pr, 0);
  vec4 result = vec4(0.0);
  if (info.w > 0.0 && all(lessThan(pr, uniform_grid))) {
    vec3 n = texelFetch(probe_normal, pr, 0).xyz;
    float voxel, db;
    vec3 pb = gi_lifted_end(info.xyz, n, voxel, db);
    float reach = 0.0;
    for (int k = 0; k < 9; k++) {
      ivec2 q = pr + ivec2(k % 3 - 1, k / 3 - 1);
      if (k != 4 && all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, uniform_grid))) {
        vec4 qi = texelFetch(probe_info, q, 0);
        reach = qi.w > 0.0 ? max(reach, distance(qi.xyz, info.xyz)) : reach;
      }
    }
    reach = 1.05 * reach + voxel;
    if (part == PROBE_OCC_TEXELS - 1) {
      result = vec4(voxel, db, reach, 1.0);
    }
    else {
      vec3 u, v;
      probe_occ_basis(n, u, v);
      for (int j = 0; j < 4; j++) {
        float theta = PROBE_OCC_STEP * float(part * 4 + j);
        float t;
        int obj;
        result[j] = gi_trace_mesh(pb, cos(theta) * u + sin(theta) * v, 0.0, reach, t, obj)
                    ? t : reach;
      }
    }
  }
  imageStore(out_image, id, result);
}
