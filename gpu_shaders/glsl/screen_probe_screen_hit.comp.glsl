#include "screen_probe_trace_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Screen probes, the light of the rays the screen walk hit something with
 * (screen_probe_screen_trace lists them in hit_list, hit_counter entries; lumen_trace_lib.glsl:
 * lumen_screen_hit: HITS "COLOUR", the screen colour), one invocation per listed hit, dispatched
 * over the count read back.
 * Inputs: screen_probe_trace_lib's, screen_trace.SAMPLERS and PUSH; images hit_list,
 * hit_counter (read).
 */
void main()
{
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= imageLoad(hit_counter, ivec2(0, 0)).x) {
    return;
  }
  int w = imageSize(hit_list).x / 2;
  ivec2 at = ivec2(2 * (slot % w), slot / w);
  vec4 entry = imageLoad(hit_list, at);
  ivec2 hit_px = ivec2(imageLoad(hit_list, at + ivec2(1, 0)).xy + 0.5);
  ivec2 tx = ivec2(entry.xy + 0.5);
  vec3 o, dir;
  float tmax;
  int level;
  if (!probe_ray(tx, o, dir, tmax, level)) {
    return;
  }
  probe_ray_store(tx, o, level, tmax, lumen_screen_hit(o, dir, entry.z, hit_px), entry.z);
}
