#include "screen_probe_trace_lib.glsl"
#include "gi_trace_lib.glsl"
/* Screen probes, tracing without the screen (screen_probe_trace_lib.glsl): every ray through the
 * mesh SDFs near, the global SDF far, the surface cache (or voxel lighting) at hits, the sky on a
 * miss (gi_trace_lib.glsl). The screen trace's passes are screen_probe_screen_trace and
 * screen_probe_trace_list: its code is not in this shader (llvmpipe pays for code that is
 * compiled in even where no lane runs it: 5-10% of this pass).
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
  vec3 L = gi_radiance(o, dir, tmax, t, w);
  probe_ray_store(tx, o, level, tmax, L, t);
}
