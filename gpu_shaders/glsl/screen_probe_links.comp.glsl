#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
/* Screen probes, which neighbours a probe can see (for screen_probe_filter): per probe, bit k of
 * the 3x3 neighbourhood (k = (dy + 1) * 3 + (dx + 1), the centre left out) is set when that
 * neighbour is a probe and no wall stands between the two (sdf_ray_lib.glsl's gi_visible, the
 * probe's own object voxel as its thin-wall scale). Why a pass of its own: the filter asked this
 * once per probe texel, 64 times the same short SDF rays per neighbour, a tenth of a viewport
 * frame (bench/pass_profile.py).
 * Inputs: probe_info, probe_normal, the mesh SDFs. Output out_image: r = the mask (0..255, exact
 * in a float). */
void main()
{
  ivec2 pr = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(probe_info, 0);
  if (pr.x >= size.x || pr.y >= size.y) {
    return;
  }
  ivec2 grid = uniform_grid;        /* adaptive probes (outside it) have no grid neighbours */
  vec4 info = texelFetch(probe_info, pr, 0);
  int mask = 0;
  if (info.w > 0.0 && all(lessThan(pr, grid))) {
    vec3 n = texelFetch(probe_normal, pr, 0).xyz;
    float voxel, da;
    vec3 pa = gi_lifted_end(info.xyz, n, voxel, da);   /* the probe's end, once for all 8 */
    vec4 ga = vec4(0.0);         /* pa's gradient, for the tests that need it */
    for (int dy = -1; dy <= 1; dy++) {
      for (int dx = -1; dx <= 1; dx++) {
        ivec2 q = pr + ivec2(dx, dy);
        if ((dx == 0 && dy == 0) || any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, grid))) {
          continue;
        }
        vec4 qi = texelFetch(probe_info, q, 0);
        if (qi.w > 0.0
            && gi_visible_from(pa, da, qi.xyz, texelFetch(probe_normal, q, 0).xyz, voxel, ga)) {
          mask |= 1 << ((dy + 1) * 3 + (dx + 1));
        }
      }
    }
  }
  imageStore(out_image, pr, vec4(float(mask), 0.0, 0.0, 0.0));
}
