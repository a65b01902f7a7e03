#include "sky_lib.glsl"
#include "camera_lib.glsl"
/* Composite: Combined = albedo * (Diffuse Direct + Diffuse Indirect) + emission (Cycles' passes:
 * Diffuse Direct / Indirect = E / pi without the albedo), the world on the background.
 * Inputs: gbuf_position, gbuf_albedo, gbuf_emission, direct (E_direct / pi), indirect (E_indirect,
 * irradiance); sky_maps (sky_lib.glsl), inv_view_proj (camera_lib.glsl), film_alpha (0: Film >
 * Transparent, the background rgba 0; the anti-aliasing's mean of samples makes edges partial);
 * a holdout's pixels (gbuffer.glsl: position w 0.25) are rgba 0.
 * Outputs: out_image = Combined, indirect_out = E_indirect / pi.
 */
#define PI 3.14159265358979

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  float w = texelFetch(gbuf_position, px, 0).w;
  if (w < 0.5) {
    vec3 ro, rd;
    camera_ray(px, size, ro, rd);
    /* w 0.25: a holdout (gbuffer.glsl): rgba 0 with or without Film > Transparent, as Cycles */
    imageStore(out_image, px, w > 0.125 ? vec4(0.0) : vec4(sky_background(rd), 1.0) * film_alpha);
    imageStore(indirect_out, px, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  vec3 ind = texelFetch(indirect, px, 0).rgb / PI;
  vec3 dir = texelFetch(direct, px, 0).rgb;
  vec3 albedo = texelFetch(gbuf_albedo, px, 0).rgb;
  vec3 emission = texelFetch(gbuf_emission, px, 0).rgb;
  imageStore(out_image, px, vec4(albedo * (dir + ind) + emission, 1.0));
  imageStore(indirect_out, px, vec4(ind, 1.0));
}
