/* Surface cache direct light: per lighting-atlas texel, the irradiance E from every light with SDF
 * cone-traced shadows (light_lib.glsl), at the texel's surface point in world space.
 * Inputs: texel_card (card row per texel, -1 none), the card tables and layers, lights,
 * light_count. Output out_image (RGBA32F): E.rgb, w = 1 where the texel holds a surface, else 0.
 * The sky is not added here: the indirect pass gets it from the rays that miss.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int row = int(texelFetch(texel_card, px, 0).x);
  vec3 pl, nl, albedo, emissive;
  if (row < 0) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  vec4 t0 = sc_card(row, 0);
  int obj = int(t0.x + 0.5);
  if (!sc_texel_surface(row, px - ivec2(t0.zw + 0.5), pl, nl, albedo, emissive)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  /* Local to world: the inverse of the object table's world-to-local rows. */
  mat4 w2l = transpose(mat4(sdf_object_texel(obj, 0), sdf_object_texel(obj, 1),
                            sdf_object_texel(obj, 2), vec4(0.0, 0.0, 0.0, 1.0)));
  mat4 l2w = inverse(w2l);
  vec3 p = (l2w * vec4(pl, 1.0)).xyz;
  vec3 n = normalize(transpose(mat3(w2l)) * nl);
  vec3 E = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    E += light_irradiance(i, p, n, light_samples, light_rotation(px));
  }
  imageStore(out_image, px, vec4(E, 1.0));
}
