#include "sdf_ray_lib.glsl"
#include "gi_trace_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 1: trace. One invocation per ray of the rows
 * surface_cache_probe_list listed (ray_rows: probe x, y, row; row_count of them): invocation i
 * traces ray (i % 4) of row entry i / 4, texel (x, y) of the ray atlas being ray (x % 4) +
 * 4 (y % 4) of probe (x / 4, y / 4) (surface_cache_probe_lib.glsl). Each ray goes through
 * gi_trace_lib.glsl from one voxel off the probe's surface and returns the surface cache's final
 * light at its hit (last frame's: one more bounce) or the sky. The probe's site and surface come
 * from surface_cache_probe_place (sc_probes, sc_probe_pos); the ray LOD and the texels not traced
 * are surface_cache_probe_list's.
 * Inputs: texel_card, card tables and layers, sc_final, sc_pages, sc_tile_frame, sc_probes,
 * sc_probe_pos, ray_rows;
 * frame, t_max, row_count.
 * Output out_image (rays): radiance rgb, a = 1 (0.5: the hit seen by no card).
 */
void main()
{
  int i = int(gl_GlobalInvocationID.x);
  int e = i / SCP_SIZE;
  if (e >= row_count) {
    return;
  }
  ivec2 lsize = textureSize(ray_rows, 0);
  vec4 entry = texelFetch(ray_rows, ivec2(e % lsize.x, e / lsize.x), 0);
  ivec2 probe = ivec2(entry.xy + 0.5);
  ivec2 local = ivec2(i - e * SCP_SIZE, int(entry.z + 0.5));
  ivec2 tx = probe * SCP_SIZE + local;
  vec4 site = texelFetch(sc_probes, probe, 0);
  vec3 n = site.xyz;
  vec4 at = texelFetch(sc_probe_pos, probe, 0);
  vec3 dir = scp_dir(probe, frame, local.x + SCP_SIZE * local.y, n);
  float t, w;
  vec3 L = gi_radiance(at.xyz + n * at.w, dir, t_max, t, w);
  imageStore(out_image, tx, vec4(L, w > 0.0 ? 1.0 : 0.5));
}
