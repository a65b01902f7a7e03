#include "sdf_ray_lib.glsl"
#include "gi_trace_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 1: trace. One invocation per probe ray: texel (x, y) of the
 * ray atlas is ray (x % 4) + 4 (y % 4) of probe (x / 4, y / 4) (surface_cache_probe_lib.glsl).
 * Each ray goes through gi_trace_lib.glsl from one voxel off the probe's surface and returns the
 * surface cache's final light at its hit (last frame's: one more bounce) or the sky.
 * Runs over this frame's tiles (sc_pages): thread (x, y) is ray texel (x % 32, y) of tile x / 32.
 * Ray LOD (lecture: the surface cache's resolution follows the card's size on screen): a probe
 * whose 4x4 texels span few pixels traces only rows of its 4x4 ray block, 2 of 4 or 1 of 4
 * (stride 2 or 4, the row frame % stride: every row in turn over the updates), so that it still
 * traces at least lod_rays rays per pixel it covers (probe side in pixels: 4 texels' world size x
 * lod_focal / distance to cam_pos; lod_focal = 0: every ray). The skipped slots are written
 * a = 0 and surface_cache_probe_sh leaves them out: fewer rays, the same expectation. Whole rows
 * of the ray block: the 8 invocations a llvmpipe SIMD row runs together skip together.
 * The probe's site and surface come from surface_cache_probe_place (sc_probes, sc_probe_pos).
 * Inputs: texel_card, card tables and layers, sc_final, sc_pages, sc_probes, sc_probe_pos;
 * frame, t_max, cam_pos, lod_focal, lod_rays.
 * Output out_image (rays): radiance rgb, a = 1 (0: no probe).
 */
void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 tx = scp_page_texel(gid);
  ivec2 size = imageSize(out_image);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  ivec2 probe = tx / SCP_SIZE;
  ivec2 local = tx - probe * SCP_SIZE;
  int k = local.x + SCP_SIZE * local.y;
  vec4 site = texelFetch(sc_probes, probe, 0);
  if (site.w < 0.5) {
    imageStore(out_image, tx, vec4(0.0));
    return;
  }
  int row = int(site.w + 0.5) - 1;
  vec3 n = site.xyz;
  vec4 at = texelFetch(sc_probe_pos, probe, 0);
  vec3 p = at.xyz;
  if (lod_focal > 0.0) {
    int obj = int(sc_card(row, 0).x + 0.5);
    vec4 t1 = sc_card(row, 1);
    vec4 t2 = sc_card(row, 2);
    vec2 local_texel = (t2.zw - t2.xy) / max(t1.zw, vec2(1.0));
    float scale = pow(abs(determinant(mat3(sc_object_w2l(obj)))), -1.0 / 3.0);
    float side = float(SCP_SIZE) * max(local_texel.x, local_texel.y) * scale * lod_focal
                 / max(distance(p, cam_pos), 1e-3);          /* the probe's side in pixels */
    float covered = side * side;
    int stride = float(SCP_RAYS / 4) >= lod_rays * covered ? 4
                 : (float(SCP_RAYS / 2) >= lod_rays * covered ? 2 : 1);
    if (local.y % stride != frame % stride) {
      imageStore(out_image, tx, vec4(0.0));      /* not traced this update */
      return;
    }
  }
  vec3 dir = scp_dir(probe, frame, k, n);
  float t, w;
  vec3 L = gi_radiance(p + n * at.w, dir, t_max, t, w);
  imageStore(out_image, tx, vec4(L, w > 0.0 ? 1.0 : 0.5));
}
