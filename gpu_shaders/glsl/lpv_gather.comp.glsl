#include "gbuffer_lib.glsl"
#include "lpv_lib.glsl"
/* LPV lookup per pixel (lpv.py; lecture 21, "Scene lighting with final light propagation
 * volume"): the accumulated grid (acc_r, acc_g, acc_b: the sum of the injected light and every
 * iteration's) read trilinearly between cell centres at x + h/2 n (half a cell in front of the
 * surface, as the injection: the cell behind a wall is not read), then the irradiance of a
 * surface of normal n: light travelling along w arrives where n . w < 0, with the radiance of
 * the cell's intensity over its face, L(w) = I(w) / h^2 (Kaplanyan and Dachsbacher 2010), so
 *     E(n) = integral L(w) max(0, -n . w) dw = dot(c, lpv_lobe(-n)) / h^2,
 * clamped at 0 (2-band SH rings: a lobe has a negative tail behind it). Inputs gbuf_position,
 * gbuf_normal, acc_r, acc_g, acc_b; push grid_origin, grid_dims, cam_pos. Output out_image: E rgb,
 * w = 1 on surfaces.
 */
vec3 lpv_irradiance(vec3 q, vec3 n)
{
  float h = grid_origin.w;
  ivec3 dims = grid_dims.xyz;
  vec3 g = clamp((q - grid_origin.xyz) / h - 0.5, vec3(0.0), vec3(dims - 1));
  ivec3 i0 = clamp(ivec3(floor(g)), ivec3(0), max(dims - 2, ivec3(0)));
  vec3 f = clamp(g - vec3(i0), 0.0, 1.0);
  vec4 r = vec4(0.0), gg = vec4(0.0), b = vec4(0.0);
  for (int k = 0; k < 8; k++) {
    ivec3 o = ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
    ivec3 c = min(i0 + o, dims - 1);
    vec3 w3 = mix(vec3(1.0) - f, f, vec3(o));
    float w = w3.x * w3.y * w3.z;
    ivec2 t = lpv_texel(c, dims);
    r += w * texelFetch(acc_r, t, 0);
    gg += w * texelFetch(acc_g, t, 0);
    b += w * texelFetch(acc_b, t, 0);
  }
  vec4 lobe = lpv_lobe(-n);
  return max(vec3(dot(r, lobe), dot(gg, lobe), dot(b, lobe)), vec3(0.0)) / (h * h);
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 x, n;
  if (!gbuf_surface(px, cam_pos, x, n)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  float h = grid_origin.w;
  vec3 E = min(lpv_irradiance(x + 0.5 * h * n, n), lpv_irradiance(x + 1.5 * h * n, n));
  imageStore(out_image, px, vec4(E, 1.0));
}
