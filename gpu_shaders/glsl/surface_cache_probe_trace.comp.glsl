#include "sdf_ray_lib.glsl"
#include "gi_trace_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 1: trace. One invocation per probe ray: texel (x, y) of the
 * ray atlas is ray (x % 4) + 4 (y % 4) of probe (x / 4, y / 4) (surface_cache_probe_lib.glsl).
 * Each ray goes through gi_trace_lib.glsl from one voxel off the probe's surface and returns the
 * surface cache's final light at its hit (last frame's: one more bounce) or the sky.
 * Runs over this frame's tiles (sc_pages): thread (x, y) is ray texel (x % 32, y) of tile x / 32.
 * Inputs: texel_card, card tables and layers, sc_final, sc_pages; frame, t_max.
 * Outputs: out_image (rays): radiance rgb, a = 1 (0: no probe); probe_out (one texel per probe,
 * written by ray 0): world normal xyz, w = card row + 1 (0: no probe); probe_pos_out: world position
 * xyz, w = the object's voxel.
 */
/* A probe's texel (scp_texel: up to 16 candidate texels, each a surface lookup and an SDF
 * sample) and its surface point are found once per probe, by its ray 0, and shared with its
 * other 15 rays: the 8x8 work group (compute.GROUP) holds 2x2 whole probes, tiles being 32
 * texels wide. Each ray finding them again cost as much as a short ray's trace. */
shared vec4 s_pos[4];      /* world position, object index (-1: no probe) */
shared vec3 s_normal[4];

void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 tx = scp_page_texel(gid);
  ivec2 size = imageSize(out_image);
  bool inside = tx.x < size.x && tx.y < size.y;
  ivec2 probe = tx / SCP_SIZE;
  ivec2 local = tx - probe * SCP_SIZE;
  int k = local.x + SCP_SIZE * local.y;
  ivec2 lid = ivec2(gl_LocalInvocationID.xy) / SCP_SIZE;
  int slot = lid.x + 2 * lid.y;
  if (k == 0 && inside) {
    ivec2 texel;
    int row;
    if (scp_texel(probe, frame, texel, row)) {
      vec3 p, n;
      int obj;
      scp_surface(texel, row, p, n, obj);
      s_pos[slot] = vec4(p, float(obj));
      s_normal[slot] = n;
      imageStore(probe_out, probe, vec4(n, float(row + 1)));
      imageStore(probe_pos_out, probe, vec4(p, gi_object_voxel(obj)));
    }
    else {
      s_pos[slot] = vec4(0.0, 0.0, 0.0, -1.0);
      imageStore(probe_out, probe, vec4(0.0));
      imageStore(probe_pos_out, probe, vec4(0.0));
    }
  }
  barrier();
  if (!inside) {
    return;
  }
  if (s_pos[slot].w < 0.0) {
    imageStore(out_image, tx, vec4(0.0));
    return;
  }
  vec3 p = s_pos[slot].xyz;
  vec3 n = s_normal[slot];
  int obj = int(s_pos[slot].w + 0.5);
  vec3 dir = scp_dir(probe, frame, k, n);
  float t, w;
  vec3 L = gi_radiance(p + n * gi_object_voxel(obj), dir, t_max, t, w);
  imageStore(out_image, tx, vec4(L, w > 0.0 ? 1.0 : 0.5));
}
