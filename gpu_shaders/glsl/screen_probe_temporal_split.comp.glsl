#include "gbuffer_lib.glsl"
#include "probe_interp_lib.glsl"
/* Screen probes, the viewport's temporal filter when one redraw integrates only one pixel of every
 * px_step x px_step block (GISettings.split = px_step^2: the viewport spreads one refinement step
 * over that many redraws). Block pixels take turns in Bayer order (split_phase: 0 3 / 2 1 for a
 * 2x2 block), so redraw `frame` (0 = the first since the history was reset) integrates the pixels
 * whose phase is frame % split. A pixel's own samples before this redraw are therefore
 * m = frame > phase ? (frame - 1 - phase) / split + 1 : 0, and nothing per pixel is stored:
 *   its turn:    mix(history, new, max(1 / (k + 1), 1 / history_len)), k = m but m - 1 from
 *                the second round on (its first-round sample is replaced: see `kept`)
 *   not its turn, m > 0: the history as it is
 *   m = 0 (not yet integrated, e.g. the first redraws after the camera moved): filled from this
 *   redraw's integrated pixels around it, by plane distance (probe_interp_lib's sharpness) and
 *   normal agreement, so a first frame costs 1 / split of the integration and shows no holes.
 * Inputs: indirect_new (this redraw's integrated pixels), indirect_history (ignored at frame 0),
 * gbuf_position, gbuf_normal; cam_pos, px_step, px_phase (this redraw's integrated block pixel),
 * frame, history_len.
 * Output out_image: E.rgb, w as the integration's (-1 background).
 */
int split_phase(ivec2 px, int step)
{
  ivec2 a = px & 1;
  int b = 2 * (a.x ^ a.y) + a.y;
  if (step <= 2) {
    return b;
  }
  ivec2 c = (px >> 1) & 1;
  return 4 * b + 2 * (c.x ^ c.y) + c.y;
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  int split = px_step * px_step;
  int phase = split_phase(px, px_step);
  int m = frame > phase ? (frame - 1 - phase) / split + 1 : 0;
  if (frame % split == phase) {
    vec4 e = texelFetch(indirect_new, px, 0);
    if (e.w == -2.0) {
      /* a turn screen_probe_fallback skipped (over its budget, from the second round on: a
       * history exists): no sample, the history as it is */
      imageStore(out_image, px, texelFetch(indirect_history, px, 0));
      return;
    }
    /* the first round's sample saw probes partly filled from a quarter of their rays
     * (screen_probe_trace's texel_fill): the second round replaces it */
    int kept = frame >= split ? m - 1 : m;
    vec3 h = kept > 0 ? texelFetch(indirect_history, px, 0).rgb : e.rgb;
    float blend = max(1.0 / float(kept + 1), 1.0 / max(history_len, 1.0));
    imageStore(out_image, px, vec4(mix(h, e.rgb, blend), e.w));
    return;
  }
  if (m > 0) {
    imageStore(out_image, px, texelFetch(indirect_history, px, 0));
    return;
  }
  /* the integrated pixels of this redraw nearest px (px_phase: the block pixel integrated
   * now): the corners of its px_step cell */
  ivec2 base = px - ((px - px_phase) % px_step + px_step) % px_step;
  float depth = max(distance(p, cam_pos), 1e-4);
  vec4 plane = vec4(n, dot(n, p));
  vec3 sum = vec3(0.0);
  float wsum = 0.0, flag = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 q = base + px_step * ivec2(k & 1, k >> 1);
    if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) {
      continue;
    }
    vec4 e = texelFetch(indirect_new, q, 0);
    if (e.w < 0.0) {
      continue;
    }
    vec4 qp = texelFetch(gbuf_position, q, 0);
    vec3 qn = normalize(texelFetch(gbuf_normal, q, 0).xyz);
    float rel = abs(dot(vec4(qp.xyz, -1.0), plane)) / depth;
    vec2 f = 1.0 - abs(vec2(px - q)) / float(px_step);
    float w = f.x * f.y * (exp2(-PROBE_PLANE_SHARPNESS * rel * rel) * abs(dot(n, qn)) + 1e-4);
    sum += w * e.rgb;
    wsum += w;
    flag = max(flag, e.w);
  }
  imageStore(out_image, px, vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), flag));
}
