#include "sampling_lib.glsl"
#include "octahedral_lib.glsl"
/* Screen probes, importance sampling (lecture: "Importance Sampling" through "Fix Budget
 * Importance Sampling based on Lighting and BRDF"): which direction each of a probe's res^2 ray
 * slots traces this frame. One work group is one probe (res = 8 = the group size), its
 * invocations its texels, sharing the probe's numbers in shared memory.
 *   BRDF:     the cosine lobes of the pixels that will use the probe: 64 pixels on an 8x8 grid
 *             over 2 tiles around the probe's pixel, accepted when the probe lies on their plane
 *             (the lecture's depth weight > 0.1; the probe's own normal always). The lecture
 *             sums their lobes in SH to save work; a work group per probe has the 64 normals in
 *             shared memory, so each texel takes the exact mean of max(0, n . d) instead.
 *   Lighting: last frame's radiance of the same probe (what was traced, screen_probe_compose's
 *             history: not the unbiased estimate, not filtered), reprojected: the history probe
 *             nearest in world position among the 3x3 around the same tile (within a quarter of
 *             the depth, normals within 60 degrees; none: the probe keeps uniform rays).
 *   The c texels whose BRDF is below CULL_FRACTION of its mean (the far side of the pixels'
 *   planes) make g = min(c / 4, res^2 - c) groups of 4; each group traces one ray (in one
 *   member drawn at random), its other 3 slots supersample one of the g texels of highest
 *   pdf = BRDF x (luminance, dilated by a texel, + the probe's mean luminance) with a 2x2
 *   quarter each: the ray count per probe stays res^2. Lighting only orders the supersampling,
 *   it culls nothing: UE also culls by lighting (and drops the light a stale prior missed);
 *   unbiased, a culled texel that meets a light the prior missed costs 4 L - 3 prior (measured:
 *   a small bright patch then raised the variance 1.5x instead of lowering it).
 * Unbiased (screen_probe_compose): a supersampled texel is the solid-angle mean of its 4
 * quarters; a culled texel is prior + 4 [drawn] (L - prior), whose expectation over the draw is
 * L's, and which is exactly L when the prior is (a uniform sky furnace stays exact).
 * Inputs: gbuf_position, gbuf_normal, probe_info, probe_normal, hist_info, hist_normal,
 * hist_radiance (last frame's probe_info, probe_normal, radiance history); cam_pos, probe_tile,
 * probe_res, frame, uniform_rows (history probes only from the same block of the atlas:
 * uniform, adaptive level 1 or 2).
 * Outputs: out_image (R32F, the slot codes of screen_probe_ray_lib.glsl), probe_plan (per texel:
 * x kind 0 one ray / 1 supersampled / 2 culled, y..w: a supersampled texel's 3 donor slots, a
 * culled texel's y = 1 when drawn), probe_prior (the prior radiance, a = its hit distance).
 */
#define CULL_FRACTION 0.1
#define RAYS_MAX 64

shared vec3 s_normal[RAYS_MAX];
shared float s_accept[RAYS_MAX];
shared float s_lum[RAYS_MAX];
shared float s_pdf[RAYS_MAX];
shared float s_brdf[RAYS_MAX];
shared int s_texel_of_rank[RAYS_MAX];

uint screen_probe_draw(ivec2 pr, int group)
{
  return pcg_hash(uint(pr.x) + 7919u * uint(pr.y)
                  ^ pcg_hash(uint(frame) * 64u + uint(group) + 0x9e3779b9u)) % 4u;
}

void main()
{
  ivec2 pr = ivec2(gl_WorkGroupID.xy);
  ivec2 texel = ivec2(gl_LocalInvocationID.xy);
  int n = probe_res * probe_res;
  int t = texel.x + texel.y * probe_res;
  ivec2 tx = pr * probe_res + texel;
  vec4 info = texelFetch(probe_info, pr, 0);
  vec4 pn = texelFetch(probe_normal, pr, 0);
  if (info.w <= 0.0) {   /* the whole group: an empty slot (adaptive levels are mostly empty) */
    imageStore(out_image, tx, vec4(0.0));
    imageStore(probe_plan, tx, vec4(0.0));
    imageStore(probe_prior, tx, vec4(0.0));
    return;
  }

  /* the history probe: nearest in world position, same side, near enough */
  bool use = info.w > 0.0;
  ivec2 hq = pr;
  if (use) {
    ivec2 hgrid = textureSize(hist_info, 0);
    int region = pr.y < uniform_rows ? 0 : (pr.y < 3 * uniform_rows ? 1 : 2);
    float best = 1e30;
    for (int dy = -1; dy <= 1; dy++) {
      for (int dx = -1; dx <= 1; dx++) {
        ivec2 q = pr + ivec2(dx, dy);
        int qr = q.y < uniform_rows ? 0 : (q.y < 3 * uniform_rows ? 1 : 2);
        if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, hgrid)) || qr != region) {
          continue;
        }
        vec4 qi = texelFetch(hist_info, q, 0);
        if (qi.w <= 0.0 || dot(texelFetch(hist_normal, q, 0).xyz, pn.xyz) < 0.5) {
          continue;
        }
        float d = distance(qi.xyz, info.xyz);
        if (d < best) {
          best = d;
          hq = q;
        }
      }
    }
    use = best < 0.25 * info.w;
  }
  vec4 prior = use ? texelFetch(hist_radiance, hq * probe_res + texel, 0) : vec4(0.0);

  /* BRDF: the normals of 64 pixels around the probe's pixel */
  ivec2 size = textureSize(gbuf_position, 0);
  int pix = int(pn.w + 0.5);
  ivec2 ppx = ivec2(pix % size.x, pix / size.x);
  int spacing = max(2 * probe_tile / probe_res, 1);
  ivec2 sp = clamp(ppx + (texel - probe_res / 2) * spacing + spacing / 2, ivec2(0), size - 1);
  vec4 pos = texelFetch(gbuf_position, sp, 0);
  vec3 nn = pn.xyz;
  float accept = 0.0;
  if (pos.w > 0.5) {
    nn = normalize(texelFetch(gbuf_normal, sp, 0).xyz);
    if (dot(nn, cam_pos - pos.xyz) < 0.0) {
      nn = -nn;
    }
    float rel = abs(dot(vec4(info.xyz, -1.0), vec4(nn, dot(nn, pos.xyz)))) / max(info.w, 1e-4);
    accept = exp2(-10000.0 * rel * rel) > 0.1 ? 1.0 : 0.0;
  }
  if (t == 0) {          /* one slot holds the probe's own normal (the lecture's centre sample) */
    nn = pn.xyz;
    accept = 1.0;
  }
  s_normal[t] = nn;
  s_accept[t] = accept;
  s_lum[t] = max(dot(prior.rgb, vec3(0.2126, 0.7152, 0.0722)), 0.0);
  barrier();

  vec3 dir = oct_texel_dir(texel, probe_res, vec2(0.5));
  float brdf = 0.0, wsum = 0.0, mean_lum = 0.0;
  for (int j = 0; j < n; j++) {
    brdf += s_accept[j] * max(dot(s_normal[j], dir), 0.0);
    wsum += s_accept[j];
    mean_lum += s_lum[j];
  }
  brdf /= max(wsum, 1.0);
  s_brdf[t] = brdf;
  mean_lum /= float(n);
  float lum = 0.0;       /* dilated by a texel: next frame's jitter can move a feature across */
  for (int dy = -1; dy <= 1; dy++) {
    for (int dx = -1; dx <= 1; dx++) {
      ivec2 q = clamp(texel + ivec2(dx, dy), ivec2(0), ivec2(probe_res - 1));
      lum = max(lum, s_lum[q.x + q.y * probe_res]);
    }
  }
  barrier();
  float mean_brdf = 0.0;
  for (int j = 0; j < n; j++) {
    mean_brdf += s_brdf[j];
  }
  mean_brdf /= float(n);
  /* culled texels rank first (key -1), the rest by pdf */
  float pdf = brdf < CULL_FRACTION * mean_brdf ? -1.0 : brdf * (lum + mean_lum + 1e-6);
  s_pdf[t] = pdf;
  barrier();

  int rank = 0;
  int culled = 0;
  for (int j = 0; j < n; j++) {
    float p = s_pdf[j];
    rank += (p < pdf || (p == pdf && j < t)) ? 1 : 0;
    culled += p < 0.0 ? 1 : 0;
  }
  int g = use ? min(culled / 4, n - culled) : 0;
  s_texel_of_rank[rank] = t;
  barrier();

  float code = 0.0;                 /* own texel, one ray */
  vec4 plan = vec4(0.0);
  if (rank < 4 * g) {               /* culled: 4 texels share one ray */
    int k = rank / 4;
    int m = rank % 4;
    int drawn = int(screen_probe_draw(pr, k));
    if (m == drawn) {
      code = float(1 + t);
      plan = vec4(2.0, 1.0, 0.0, 0.0);
    }
    else {
      int sub = 1 + (m < drawn ? m : m - 1);
      code = float(1 + s_texel_of_rank[n - 1 - k] + n * (sub + 1));
      plan = vec4(2.0, 0.0, 0.0, 0.0);
    }
  }
  else if (rank >= n - g) {         /* supersampled: its quarter 0, the donors 1..3 */
    int k = n - 1 - rank;
    int drawn = int(screen_probe_draw(pr, k));
    vec3 donors = vec3(0.0);
    int d = 0;
    for (int m = 0; m < 4; m++) {
      if (m != drawn) {
        donors[d] = float(s_texel_of_rank[4 * k + m]);
        d++;
      }
    }
    code = float(1 + t + n);
    plan = vec4(1.0, donors);
  }
  imageStore(out_image, tx, vec4(code, 0.0, 0.0, 0.0));
  imageStore(probe_plan, tx, plan);
  imageStore(probe_prior, tx, prior);
}
