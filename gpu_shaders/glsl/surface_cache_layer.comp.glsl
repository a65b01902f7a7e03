#include "surface_cache_texel_lib.glsl"
/* Surface cache layer view: one value per lighting-atlas texel, for the debug views and tests.
 * layer_mode: 0 albedo, 1 world normal * 0.5 + 0.5, 2 direct E / pi, 3 indirect E / pi,
 * 4 world position, 5 a colour per card row, 6 final radiance, 7 update heat: frames since the
 * texel's tile was last relit (surface_cache_pages.py), green (this frame) to red (8 or more),
 * magenta never since the lighting was reset.
 * Inputs: as surface_cache_direct (texel_card, card tables and layers), sc_direct, sc_indirect,
 * sc_tile_age (per 32x32 tile: frames since its update, -1 never).
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
  int row, obj;
  vec3 p, n, albedo, emissive;
  if (!sc_lighting_texel(px, row, obj, p, n, albedo, emissive)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  vec3 v;
  if (layer_mode == 0) {
    v = albedo;
  }
  else if (layer_mode == 1) {
    v = n * 0.5 + 0.5;
  }
  else if (layer_mode == 2) {
    v = texelFetch(sc_direct, px, 0).rgb / PI;
  }
  else if (layer_mode == 3) {
    v = texelFetch(sc_indirect, px, 0).rgb / PI;
  }
  else if (layer_mode == 4) {
    v = p;
  }
  else if (layer_mode == 5) {
    v = sc_row_colour(row);
  }
  else if (layer_mode == 7) {
    float age = texelFetch(sc_tile_age, px / 32, 0).x;
    float t = clamp(age / 8.0, 0.0, 1.0);
    v = age < 0.0 ? vec3(1.0, 0.0, 1.0) : vec3(t, 1.0 - t, 0.0);
  }
  else {
    v = texelFetch(sc_final, px, 0).rgb;
  }
  imageStore(out_image, px, vec4(v, 1.0));
}
