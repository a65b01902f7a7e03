/* Surface cache layer view: one value per lighting-atlas texel, for the debug views and tests.
 * layer_mode: 0 albedo, 1 world normal * 0.5 + 0.5, 2 direct E / pi, 3 indirect E / pi,
 * 4 world position, 5 a colour per card row, 6 final radiance.
 * Inputs: as surface_cache_direct (texel_card, card tables and layers), sc_direct, sc_indirect.
 * Output out_image: rgb, w = 1 where the texel holds a surface, else 0.
 */
#define PI 3.14159265358979

vec3 sc_row_colour(int row)
{
  uint h = uint(row) * 2654435761u + 0x9e3779b9u;
  h ^= h >> 15u;
  h *= 2246822519u;
  h ^= h >> 13u;
  return 0.25 + 0.75 * vec3(float(h & 255u), float((h >> 8u) & 255u), float((h >> 16u) & 255u)) / 255.0;
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int row = int(texelFetch(texel_card, px, 0).x);
  vec3 pl, nl, albedo, emissive;
  if (row < 0 || !sc_texel_surface(row, px - ivec2(sc_card(row, 0).zw + 0.5), pl, nl, albedo, emissive)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  int obj = int(sc_card(row, 0).x + 0.5);
  mat4 w2l = transpose(mat4(sdf_object_texel(obj, 0), sdf_object_texel(obj, 1),
                            sdf_object_texel(obj, 2), vec4(0.0, 0.0, 0.0, 1.0)));
  vec3 v;
  if (layer_mode == 0) {
    v = albedo;
  }
  else if (layer_mode == 1) {
    v = normalize(transpose(mat3(w2l)) * nl) * 0.5 + 0.5;
  }
  else if (layer_mode == 2) {
    v = texelFetch(sc_direct, px, 0).rgb / PI;
  }
  else if (layer_mode == 3) {
    v = texelFetch(sc_indirect, px, 0).rgb / PI;
  }
  else if (layer_mode == 4) {
    v = (inverse(w2l) * vec4(pl, 1.0)).xyz;
  }
  else if (layer_mode == 5) {
    v = sc_row_colour(row);
  }
  else {
    v = texelFetch(sc_final, px, 0).rgb;
  }
  imageStore(out_image, px, vec4(v, 1.0));
}
