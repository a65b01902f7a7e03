/* Reflective shadow map, flux (rsm.py; lecture 21, "Reflective Shadow Maps"): per texel of a
 * light's map (the G-buffer pass drawn from the light: rsm_position, rsm_normal, rsm_albedo) the
 * flux the surface there reflects, Phi = albedo x (the flux the light sends through the texel):
 *   sun:   E x A, A = texel_area (the orthographic texel's area across the light)
 *   other: I x the texel's solid angle (2 tan_half / res)^2 / (1 + u^2 + v^2)^1.5, (u, v) the
 *          texel centre on the image plane at distance 1; I the row's intensity, times the spot
 *          mask (spot) or max(cos, 0) from the light's normal (area: a one-sided emitter I0 cos)
 * (lights sampler: operators/lights.py rows; row light_index). The normal is turned to the light
 * (a surface is lit on the side the light sees). Each texel is a small area light; no occlusion
 * is ever tested for its bounce (the lecture's RSM).
 * Outputs: flux_out = (Phi rgb, the texel's world area: its clamp on 1 / d^2 and the debug
 * view's radiance Phi / (pi A)), normal_out = (normal, 1) where the map shows a surface, else 0.
 */
void main()
{
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(rsm_position, 0);
  if (t.x >= size.x || t.y >= size.y) {
    return;
  }
  vec4 pos = texelFetch(rsm_position, t, 0);
  if (pos.w < 0.5) {
    imageStore(flux_out, t, vec4(0.0));
    imageStore(normal_out, t, vec4(0.0));
    return;
  }
  vec4 t0 = texelFetch(lights, ivec2(0, light_index), 0);
  vec4 t1 = texelFetch(lights, ivec2(1, light_index), 0);
  vec4 t2 = texelFetch(lights, ivec2(2, light_index), 0);
  vec4 t3 = texelFetch(lights, ivec2(3, light_index), 0);
  vec3 n = normalize(texelFetch(rsm_normal, t, 0).xyz);
  vec3 albedo = texelFetch(rsm_albedo, t, 0).rgb;
  vec3 to_light;
  vec3 phi;
  float area;
  if (int(t0.x + 0.5) == 0) {
    to_light = -t1.xyz;
    phi = t2.rgb * texel_area;
    area = texel_area / max(abs(dot(n, to_light)), 0.05);
  }
  else {
    vec3 d = pos.xyz - t0.yzw;
    float r = length(d);
    to_light = -d / max(r, 1e-6);
    vec2 uv = ((vec2(t) + 0.5) / vec2(size) * 2.0 - 1.0) * tan_half;
    float q = 1.0 + dot(uv, uv);
    float omega = pow(2.0 * tan_half / float(size.x), 2.0) / (q * sqrt(q));
    int type = int(t0.x + 0.5);
    float cos_l = dot(-to_light, t1.xyz);
    float mask = 1.0;
    if (type == 2) {
      float cos_half = t3.x;
      float smooth_w = t3.y * (1.0 - cos_half);
      float m = smooth_w > 0.0 ? clamp((cos_l - cos_half) / smooth_w, 0.0, 1.0) :
                                 (cos_l > cos_half ? 1.0 : 0.0);
      mask = m * m * (3.0 - 2.0 * m);
    }
    else if (type == 3) {
      mask = max(cos_l, 0.0);
      if (t3.w >= 0.0 && cos_l > 0.0) {   /* Spread, as light_lib.glsl's */
        float tan_a = sqrt(max(1.0 - cos_l * cos_l, 0.0)) / cos_l;
        mask *= max(1.0 - tan_a / max(t3.w, 1e-4), 0.0);
      }
    }
    phi = t2.rgb * mask * omega;
    area = omega * r * r / max(abs(dot(n, to_light)), 0.05);
  }
  if (dot(n, to_light) < 0.0) {
    n = -n;
  }
  imageStore(flux_out, t, vec4(albedo * phi, area));
  imageStore(normal_out, t, vec4(n, 1.0));
}
