#include "screen_probe_trace_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Screen probes, Lumen's first trace with HITS "CACHE" (the default; lumen_trace_lib.glsl:
 * lumen_screen_free): every ray walks the screen (HZB) only as far as the depth buffer vouches
 * for it, then goes on through the mesh SDFs, the global SDF and the sky from there
 * (gi_radiance_from), which find and read its hit as they do without the screen.
 * One pass and not the COLOUR mode's three over compacted lists: every ray takes both parts
 * here, so no lane waits on another's kind of work, and neither a list nor a count read back
 * (a CPU-GPU sync) is needed.
 * Inputs: screen_probe_trace_lib's, screen_trace.SAMPLERS and PUSH.
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
  float t, w;
  ivec2 near_px;
  vec3 L = gi_radiance_from(o, dir, lumen_screen_free(o, dir, tmax, near_px), tmax, t, w);
  probe_ray_store(tx, o, level, tmax, L, t);
}
