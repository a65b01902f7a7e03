#include "octahedral_lib.glsl"
/* Lumen GI: the direction of a screen-probe ray slot (importance sampling, screen_probe_rays).
 *
 *   vec3 screen_probe_ray_dir(ivec2 tx, int probe_res, vec2 jitter)
 *     tx: the slot in the probe atlas (probe (i, j) at [i*res, (i+1)*res) x [j*res, ...)).
 *     probe_rays (R32F, one code per slot, screen_probe_rays) says which octahedral texel of the
 *     slot's probe it traces: 0 = its own texel, as without importance sampling; else
 *     code - 1 = target + res^2 (sub + 1) with target = x + res y the texel and sub = -1 the whole
 *     texel (direction jittered inside it) or 0..3 a quarter of it (2x2 at 2 res: the texel
 *     supersampled with the rays of culled texels). The slot's weight is applied afterwards by
 *     screen_probe_compose; a tracer needs only the direction.
 * Needs octahedral_lib.glsl and the sampler probe_rays.
 */
#ifndef LUMEN_SCREEN_PROBE_RAY_LIB
#define LUMEN_SCREEN_PROBE_RAY_LIB

vec3 screen_probe_ray_dir(ivec2 tx, int probe_res, vec2 jitter)
{
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  float v = texelFetch(probe_rays, tx, 0).r;
  if (v < 0.5) {
    return oct_texel_dir(texel, probe_res, jitter);
  }
  int n = probe_res * probe_res;
  int code = int(v + 0.5) - 1;
  int target = code % n;
  int sub = code / n - 1;
  ivec2 t = ivec2(target % probe_res, target / probe_res);
  if (sub < 0) {
    return oct_texel_dir(t, probe_res, jitter);
  }
  return oct_texel_dir(2 * t + ivec2(sub % 2, sub / 2), 2 * probe_res, jitter);
}

#endif /* LUMEN_SCREEN_PROBE_RAY_LIB */
