#include "lpv_lib.glsl"
/* LPV injection (lpv.py; lecture 21, "Light Injection"): one point per texel of a light's
 * reflective shadow map (rsm.py: rsm_position, rsm_normal turned to the light, rsm_flux = the
 * flux Phi the texel reflects), drawn with additive blending into the grid's three textures
 * (colour attachments out_r, out_g, out_b: lpv_lib.glsl's layout), so every cell sums its
 * virtual point lights. Each texel is a Lambertian emitter, intensity Phi / pi max(0, n . w): its
 * cosine lobe's SH (lpv_lobe), in the cell holding p + h/2 n (Kaplanyan and Dachsbacher 2010:
 * half a cell along the normal, so a surface does not light or shadow its own cell). Texels where
 * the map shows nothing are sent outside the clip volume. Vertex input idx (the texel's index,
 * row-major); push grid_origin, grid_dims, rsm_res.
 * The vertex and fragment stages are separated by the marker line "// FRAGMENT" (without the
 * space).
 */
void main()
{
  int i = int(idx + 0.5);
  ivec2 t = ivec2(i % rsm_res, i / rsm_res);
  vec4 nrm = texelFetch(rsm_normal, t, 0);
  gl_PointSize = 1.0;
  v_r = vec4(0.0);
  v_g = vec4(0.0);
  v_b = vec4(0.0);
  if (nrm.w < 0.5) {
    gl_Position = vec4(-2.0, -2.0, 0.0, 1.0);
    return;
  }
  vec3 n = normalize(nrm.xyz);
  vec3 p = texelFetch(rsm_position, t, 0).xyz;
  vec3 flux = texelFetch(rsm_flux, t, 0).rgb;
  float h = grid_origin.w;
  ivec3 dims = grid_dims.xyz;
  ivec3 c = clamp(ivec3(floor((p + 0.5 * h * n - grid_origin.xyz) / h)), ivec3(0), dims - 1);
  vec2 size = vec2(float(dims.x), float(dims.y * dims.z));
  gl_Position = vec4((vec2(lpv_texel(c, dims)) + 0.5) / size * 2.0 - 1.0, 0.0, 1.0);
  vec4 lobe = lpv_lobe(n) / LPV_PI;
  v_r = flux.r * lobe;
  v_g = flux.g * lobe;
  v_b = flux.b * lobe;
}
//FRAGMENT
void main()
{
  out_r = v_r;
  out_g = v_g;
  out_b = v_b;
}
