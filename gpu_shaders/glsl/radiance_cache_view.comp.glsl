#include "gbuffer_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_lib.glsl"
/* The world radiance cache seen from the camera (the RADIANCE_CACHE debug view): per G-buffer
 * pixel, what the cache gives a ray leaving the surface along its normal (rc_lookup at a point
 * 1 cm off the surface: its 8 probes, parallax, visibility), from the finest level holding it.
 * Inputs: gbuf_position, gbuf_normal, the cache's samplers; cam_pos, rc_camera.
 * Output out_image: rgb, w = the level + 1; magenta, w = 0 where no traced probe serves the point
 * (none allocated there yet, or every probe around it behind a surface); background w = -1.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  vec3 o = p + 0.01 * n;
  int k = rc_level(o);
  vec3 L;
  if (rc_lookup(o, n, k, L)) {
    imageStore(out_image, px, vec4(L, float(k + 1)));
  }
  else {
    imageStore(out_image, px, vec4(1.0, 0.0, 1.0, 0.0));
  }
}
