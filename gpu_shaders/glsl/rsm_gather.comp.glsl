#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
/* RSM one-bounce gather (rsm.py; lecture 21, "Reflective Shadow Maps", "Cone Tracing with RSM"):
 * the irradiance at pixel x (normal n) from one light's RSM texels, each a small Lambertian area
 * light of flux Phi_p at x_p with normal n_p:
 *     E_p(x, n) = Phi_p max(0, n_p . (x - x_p)) max(0, n . (x_p - x)) / (pi |x - x_p|^4)
 * (the paper's formula with the 1 / pi of a Lambertian emitter's intensity Phi cos / pi; |x -
 * x_p|^2 clamped to the texel's area, so a texel next to x stays finite), summed over the map
 * without any occlusion test (as the lecture says). The sum is estimated from `samples` texels
 * importance-sampled around x's own texel c in the map (the paper's pattern: dense near c, the
 * weights growing with the distance): polar offsets r = r_max xi1, phi = 2 pi xi2 from a
 * Hammersley set rotated per pixel and frame, pdf = 1 / (2 pi r r_max) per texel area, r_max the
 * distance from c to the farthest map corner, so every texel can be drawn and the estimate is
 * unbiased (whatever c is: c only shapes the variance).
 * Inputs: gbuf_position, gbuf_normal, rsm_position, rsm_normal, rsm_flux; push light_vp, cam_pos,
 * samples, frame, accumulate (0: write, 1: add to what out_image holds: the lights before).
 * Output out_image (READ | WRITE): E rgb, w = 1 on surfaces.
 */
#define PI 3.14159265358979

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec4 before = accumulate != 0 ? imageLoad(out_image, px) : vec4(0.0);
  vec3 x, n;
  if (!gbuf_surface(px, cam_pos, x, n)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  ivec2 res = textureSize(rsm_position, 0);
  vec4 h = light_vp * vec4(x, 1.0);
  /* x's texel, kept on the map (a point outside a perspective map's frustum, or behind it, has
   * its nearest texels at the map's edge, or none: the centre), so no sample is wasted off it */
  vec2 c = h.w > 1e-6 ? clamp((h.xy / h.w * 0.5 + 0.5) * vec2(res), vec2(0.0), vec2(res)) :
                        0.5 * vec2(res);
  vec2 far_ = max(abs(c), abs(c - vec2(res)));
  float r_max = length(far_);
  uint seed = pcg_hash(uint(px.x) * 9781u + uint(px.y) * 6271u + uint(frame) * 26699u + 17u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 E = vec3(0.0);
  for (int i = 0; i < samples; i++) {
    vec2 u = fract(hammersley(uint(i), uint(samples)) + rot);
    float r = r_max * u.x;
    float a = SAMPLING_TWO_PI * u.y;
    ivec2 t = ivec2(floor(c + r * vec2(cos(a), sin(a))));
    if (t.x < 0 || t.y < 0 || t.x >= res.x || t.y >= res.y) {
      continue;
    }
    vec4 np = texelFetch(rsm_normal, t, 0);
    if (np.w < 0.5) {
      continue;
    }
    vec4 flux = texelFetch(rsm_flux, t, 0);
    vec3 d = x - texelFetch(rsm_position, t, 0).xyz;
    float d2 = max(dot(d, d), flux.w);
    float geo = max(dot(np.xyz, d), 0.0) * max(-dot(n, d), 0.0) / (PI * d2 * d2);
    E += flux.rgb * geo * (SAMPLING_TWO_PI * r * r_max);
  }
  E /= float(max(samples, 1));
  imageStore(out_image, px, vec4(before.rgb + E, 1.0));
}
