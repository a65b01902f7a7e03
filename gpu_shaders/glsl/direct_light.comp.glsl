/* Lumen GI direct light per pixel from the G-buffer (needs sdf_lib.glsl, light_lib.glsl).
 *
 * Inputs: gbuf_position, gbuf_normal, gbuf_albedo, gbuf_emission (gbuffer.glsl), lights
 * (RGBA32F, 4 texels per light row, operators/lights.py), push constants light_count, sky (uniform
 * sky radiance, linear RGB), cam_pos (world), sky_cones (number of sky occlusion cones).
 * Outputs (RGBA32F):
 *   direct_out:   Cycles' "Diffuse Direct" convention: E / pi, E the direct irradiance from the
 *                 lights and the sky (a Lambert BSDF without its albedo); 0 on the background
 *   combined_out: albedo * direct + emission; the sky radiance on the background
 * Lights, shadows and sky visibility: light_lib.glsl. sky_cones = 0 leaves the sky out (the GI
 * passes add it from their rays' misses instead).
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(direct_out);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec4 pos = texelFetch(gbuf_position, px, 0);
  if (pos.w < 0.5) {
    imageStore(direct_out, px, vec4(0.0, 0.0, 0.0, 1.0));
    imageStore(combined_out, px, vec4(sky, 1.0));
    return;
  }
  vec3 p = pos.xyz;
  vec3 n = normalize(texelFetch(gbuf_normal, px, 0).xyz);
  if (dot(n, cam_pos - p) < 0.0) {
    n = -n; /* back face: shade the side the camera sees, as Cycles does */
  }
  vec3 E = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    E += light_irradiance(i, p, n, light_samples, light_rotation(px));
  }
  if (sky_cones > 0 && any(greaterThan(sky, vec3(0.0)))) {
    E += PI * sky * sky_visibility(p, n, sky_cones);
  }
  vec3 direct = E / PI;
  vec3 albedo = texelFetch(gbuf_albedo, px, 0).rgb;
  vec3 emission = texelFetch(gbuf_emission, px, 0).rgb;
  imageStore(direct_out, px, vec4(direct, 1.0));
  imageStore(combined_out, px, vec4(albedo * direct + emission, 1.0));
}
