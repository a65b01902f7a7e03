#include "screen_probe_trace_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Screen probes, Lumen's first trace with the screen colour's hits (screen_trace.HITS "COLOUR";
 * "CACHE" runs screen_probe_lumen_trace), its walk (screen_probe_trace_lib.glsl,
 * lumen_trace_lib.glsl: lumen_screen_walk): every ray walks the screen (HZB). A ray the walk
 * finds a hit for is appended to hit_list (two texels an entry: atlas texel xy, hit distance,
 * t_free; hit pixel xy) for screen_probe_screen_hit, which reads its light; every other one to
 * ray_list (atlas texel xy, t_free: how far the depth buffer shows it empty) for
 * screen_probe_trace_list, which traces the SDFs from t_free. Slots from the atomic counters
 * hit_counter and ray_counter (cleared before).
 * Why three passes and not one: a work group runs as long as its slowest ray (llvmpipe's lanes, a
 * GPU's waves), and code a shader holds costs on llvmpipe even where no lane runs it. Traced in
 * one pass, a probe whose rays the screen mostly resolves still waited on the few that went on
 * through the SDFs (bench/f12_ab.py: screen_probe_trace 18.7 s with it against 16.3 s without,
 * cornell 128 px); with the hits' light read in the walk, every group of lanes paid the read
 * (one hit among them is enough) and the walk carried the read's code: the walk alone costs a
 * fifth of the two (bench/f12_ab.py, cornell 128 px: 0.43 against 2.25 CPU s). Lumen compacts its
 * rays between its screen, mesh-SDF and global-SDF passes for the same reason.
 * Inputs: screen_probe_trace_lib's, screen_trace.SAMPLERS and PUSH; images hit_list (RGBA32F, at
 * least twice the dispatch's size), hit_counter, ray_list (RGBA32F, at least the dispatch's
 * size), ray_counter (R32I 1x1).
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
  float t_free, ts;
  ivec2 hit_px;
  if (lumen_screen_walk(o, dir, tmax, t_free, ts, hit_px)) {
    int slot = imageAtomicAdd(hit_counter, ivec2(0, 0), 1);
    int w = imageSize(hit_list).x / 2;
    ivec2 at = ivec2(2 * (slot % w), slot / w);
    imageStore(hit_list, at, vec4(vec2(tx), ts, t_free));
    imageStore(hit_list, at + ivec2(1, 0), vec4(vec2(hit_px), 0.0, 0.0));
    return;
  }
  int slot = imageAtomicAdd(ray_counter, ivec2(0, 0), 1);
  ivec2 lsize = imageSize(ray_list);
  imageStore(ray_list, ivec2(slot % lsize.x, slot / lsize.x), vec4(vec2(tx), t_free, 0.0));
}
