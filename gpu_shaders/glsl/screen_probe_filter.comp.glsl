#include "octahedral_lib.glsl"
/* Screen probes, spatial filter (lecture: "Denoise: Spatial filtering for Probe"): each probe
 * texel averages the same direction's texel of the 3x3 neighbouring probes (a tile each, 16 or
 * 8 px: GISettings.probe_tile_for; a 3x3-tile filter for the price of 9 reads), weighted by
 *   - a plane weight: the neighbour's distance to this probe's tangent plane relative to the
 *     probe's camera distance, exp2(-FILTER_SHARPNESS rel^2) (depth weighting; normals ignored);
 *   - angle-error rejection: the neighbour's hit point seen from this probe must lie within
 *     FILTER_MAX_ANGLE of the texel's direction (else the neighbour saw something this probe
 *     sees elsewhere: parallax near occluders); sky misses are far and pass;
 *   - hit-distance clamp: a neighbour's hit closer than this probe's own is trusted only up to
 *     the own distance (its occluder might not be in this probe's view);
 *   - visibility: a neighbour that a wall hides from this probe is left out (an inside probe
 *     next to a thin wall must not average the outside's sky): probe_links, once per probe.
 * Inputs: probe_info, probe_normal, probe_radiance, probe_links (screen_probe_links);
 * probe_res, ray_jitter, uniform_grid (the uniform probes' block of the atlas: an adaptive probe,
 * screen_probe_adaptive, has no grid neighbours and keeps its own radiance).
 * Output out_image: filtered radiance rgb, a = own hit distance.
 */
#define FILTER_SHARPNESS 1000.0
#define FILTER_MAX_ANGLE_COS 0.9848   /* 10 degrees */

void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  ivec2 grid = uniform_grid;        /* neighbours among the uniform probes only */
  bool uniform_probe = all(lessThan(pr, grid));
  vec4 info = texelFetch(probe_info, pr, 0);
  vec4 own = texelFetch(probe_radiance, tx, 0);
  if (info.w <= 0.0) {
    imageStore(out_image, tx, own);
    return;
  }
  vec3 n = texelFetch(probe_normal, pr, 0).xyz;
  vec4 plane = vec4(n, dot(n, info.xyz));
  vec3 dir = oct_texel_dir(texel, probe_res, ray_jitter);
  int links = int(texelFetch(probe_links, pr, 0).r + 0.5);
  vec3 sum = own.rgb;
  float wsum = 1.0;
  for (int dy = -1; dy <= 1; dy++) {
    for (int dx = -1; dx <= 1; dx++) {
      ivec2 q = pr + ivec2(dx, dy);
      if (!uniform_probe || (dx == 0 && dy == 0) || any(lessThan(q, ivec2(0)))
          || any(greaterThanEqual(q, grid))) {
        continue;
      }
      vec4 qi = texelFetch(probe_info, q, 0);
      if (qi.w <= 0.0) {
        continue;
      }
      float rel = abs(dot(vec4(qi.xyz, -1.0), plane)) / info.w;
      float w = exp2(-FILTER_SHARPNESS * rel * rel);
      vec4 s = texelFetch(probe_radiance, q * probe_res + texel, 0);
      float hit = min(s.a, own.a);
      vec3 seen = qi.xyz + dir * hit - info.xyz;
      float len = length(seen);
      if (len > 1e-4 && dot(seen / len, dir) < FILTER_MAX_ANGLE_COS) {
        continue;
      }
      if ((links & (1 << ((dy + 1) * 3 + (dx + 1)))) == 0) {
        continue;
      }
      sum += w * s.rgb;
      wsum += w;
    }
  }
  imageStore(out_image, tx, vec4(sum / wsum, own.a));
}
