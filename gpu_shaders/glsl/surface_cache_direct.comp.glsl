#include "sdf_ray_lib.glsl"
#include "surface_cache_lib.glsl"
#include "light_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_texel_lib.glsl"
/* Surface cache direct light: per lighting-atlas texel, the irradiance E from every light with SDF
 * cone-traced shadows (light_lib.glsl), at the texel's surface point in world space.
 * Inputs: texel_card (card row per texel, -1 none), the card tables and layers, lights,
 * light_count. Output out_image (RGBA32F): E.rgb, w = 1 where the texel holds a surface, else 0.
 * Plus sc_near_emission: emissive texels facing the texel from under 1.5 voxels, where no GI ray
 * reaches (surface_cache_lib.glsl). The sky is not added here: the indirect pass gets it from the rays that miss.
 * Runs over this frame's tiles (sc_pages, surface_cache_pages_lib.glsl); the others keep theirs.
 */
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
  vec3 E = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    E += light_irradiance(i, p, n, light_samples, light_rotation(px));
  }
  E += sc_near_emission(p, n, gi_object_voxel(obj));   /* emitters nearer than the rays reach */
  imageStore(out_image, px, vec4(E, 1.0));
}
