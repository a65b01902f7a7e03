#include "screen_probe_trace_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Screen probes, Lumen's first trace (screen_probe_trace_lib.glsl, lumen_trace_lib.glsl): every
 * ray walks the screen (HZB); a ray the screen resolves is stored; every other one is appended
 * to ray_list (its atlas texel xy and t_free, how far the depth buffer shows it empty; slot from
 * the atomic counter ray_counter, cleared before) for screen_probe_trace_list, which traces the
 * SDFs from t_free with its invocations full.
 * Why compacted: a work group runs as long as its slowest ray (llvmpipe's lanes, a GPU's
 * waves); traced in one pass, a probe whose rays the screen mostly resolves still waited on the
 * few that went on through the SDFs, and the screen trace saved nothing (bench/f12_ab.py:
 * screen_probe_trace 18.7 s with it against 16.3 s without, cornell 128 px) — Lumen compacts
 * its rays between the screen, mesh-SDF and global-SDF passes for the same reason.
 * Inputs: screen_probe_trace_lib's, screen_trace.SAMPLERS and PUSH; images ray_list (RGBA32F,
 * at least the dispatch's size), ray_counter (R32I 1x1).
 */
void main()
{
  ivec2 tx;
  vec3 o, dir;
  float tmax;
  int level;
  if (!probe_begin(tx, o, dir, tmax, level)) {
    return;
  }
  float t_free, t;
  vec3 L;
  if (lumen_screen(o, dir, tmax, t_free, t, L)) {
    probe_ray_store(tx, o, level, tmax, L, t);
    return;
  }
  int slot = imageAtomicAdd(ray_counter, ivec2(0, 0), 1);
  ivec2 lsize = imageSize(ray_list);
  imageStore(ray_list, ivec2(slot % lsize.x, slot / lsize.x), vec4(vec2(tx), t_free, 0.0));
}
