#include "surface_cache_pages_lib.glsl"
#include "surface_cache_texel_lib.glsl"
/* Surface cache final lighting (the lecture's "Combine Lighting"), per lighting-atlas texel:
 *   final = (E_direct + E_indirect) * albedo / pi + emissive      (radiance, Lambert)
 * Inputs: sc_direct, sc_indirect (irradiance, rgb), the card layers, sc_pages (this frame's
 * tiles: the others keep their final light). Output out_image: final.rgb, w = 1 where the texel
 * holds a surface.
 */
#define PI 3.14159265358979

void main()
{
  ivec2 px = scp_page_texel(ivec2(gl_GlobalInvocationID.xy));
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
  vec3 E = texelFetch(sc_direct, px, 0).rgb + texelFetch(sc_indirect, px, 0).rgb;
  imageStore(out_image, px, vec4(E * albedo / PI + emissive, 1.0));
}
