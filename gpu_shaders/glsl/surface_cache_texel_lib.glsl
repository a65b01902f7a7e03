#include "surface_cache_lib.glsl"
/* Lumen GI: the lighting-atlas texel a surface-cache pass runs on (needs surface_cache_lib.glsl
 * and the texel_card sampler every such pass declares, surface_cache.pass_shader).
 * sc_lighting_texel: texel px's card row, object, the surface in the object's local space and in
 * world space (position, unit normal), albedo and emissive; false where no card is or the card
 * saw nothing. */
bool sc_lighting_texel(ivec2 px, out int row, out int obj, out vec3 p, out vec3 n, out vec3 albedo,
                       out vec3 emissive)
{
  row = int(texelFetch(texel_card, px, 0).x);
  obj = -1;
  p = n = albedo = emissive = vec3(0.0);
  if (row < 0) {
    return false;
  }
  vec4 t0 = sc_card(row, 0);
  obj = int(t0.x + 0.5);
  vec3 pl, nl;
  if (!sc_texel_surface(row, px - ivec2(t0.zw + 0.5), pl, nl, albedo, emissive)) {
    return false;
  }
  mat4 w2l = sc_object_w2l(obj);
  p = (inverse(w2l) * vec4(pl, 1.0)).xyz;
  n = normalize(transpose(mat3(w2l)) * nl);
  return true;
}
