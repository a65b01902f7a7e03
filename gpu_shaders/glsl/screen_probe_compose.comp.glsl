#include "octahedral_lib.glsl"
/* Screen probes, the texel atlas from importance-sampled rays (screen_probe_rays): per
 * octahedral texel, an unbiased estimate of its radiance from the ray slots that traced it.
 *   one ray (kind 0)      its own slot, as without importance sampling;
 *   supersampled (1)      the solid-angle weighted mean of its 4 quarters (its own slot and the
 *                         3 donor slots of the plan); hit distance: the nearest;
 *   culled (2)            prior + 4 (L - prior) in the group's drawn texel (drawn with
 *                         probability 1/4), the prior elsewhere: E = L either way; hit distance:
 *                         the drawn ray's, the prior's elsewhere.
 * Inputs: probe_traced (screen_probe_trace's slots), probe_plan, probe_prior; probe_res.
 * Output out_image: radiance rgb, a = hit distance (-1: no probe), as screen_probe_trace's;
 * probe_history_out: the same but a culled texel holds what was traced in it (the drawn one)
 * or its prior: next frame's prior. Why not the estimate itself: 4 L - 3 prior fed back as the
 * next prior is a random walk whose variance grows 9x with every draw (measured: texels of
 * -480 and +1450 after 15 frames, from a patch of radiance 25).
 */
void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  vec4 own = texelFetch(probe_traced, tx, 0);
  vec4 plan = texelFetch(probe_plan, tx, 0);
  int kind = int(plan.x + 0.5);
  if (own.a == -1.0 || kind == 0) {
    imageStore(out_image, tx, own);
    imageStore(probe_history_out, tx, own);
    return;
  }
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  if (kind == 2) {
    vec4 prior = texelFetch(probe_prior, tx, 0);
    bool drawn = plan.y > 0.5;
    imageStore(out_image, tx, drawn ? vec4(prior.rgb + 4.0 * (own.rgb - prior.rgb), own.a) : prior);
    imageStore(probe_history_out, tx, drawn ? own : prior);
    return;
  }
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  float hit = own.a;
  for (int q = 0; q < 4; q++) {
    vec4 s = own;
    if (q > 0) {
      int slot = int(plan[q] + 0.5);
      s = texelFetch(probe_traced, pr * probe_res + ivec2(slot % probe_res, slot / probe_res), 0);
    }
    float w = oct_texel_solid_angle(2 * texel + ivec2(q % 2, q / 2), 2 * probe_res);
    sum += w * s.rgb;
    wsum += w;
    hit = min(hit, s.a);
  }
  imageStore(out_image, tx, vec4(sum / wsum, hit));
  imageStore(probe_history_out, tx, vec4(sum / wsum, hit));
}
