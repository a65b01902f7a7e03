#include "global_sdf_lib.glsl"
#include "gbuffer_lib.glsl"
#include "voxel_lighting_lib.glsl"
/* Voxel lighting seen from the camera (the VOXEL_LIGHTING debug view): per G-buffer pixel, what a
 * global-SDF hit there would read (vl_sample along the camera ray with the G-buffer normal, at the
 * point where such a hit stops: within the thin-wall margin off the surface), from the finest
 * clipmap level holding the point.
 * Inputs: gbuf_position, gbuf_normal; cam_pos. Output out_image: rgb, w = the level + 1;
 * magenta, w = 0 where no voxel face serves the point (a global-SDF hit there reads the surface
 * cache); background: black, w = -1.
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
  int level;
  float v;
  global_sdf_sample(p, level, v);
  vec3 L;
  if (vl_sample(level, p + n * gsdf.band.y, normalize(p - cam_pos), n, L)) {
    imageStore(out_image, px, vec4(L, float(level + 1)));
  }
  else {
    imageStore(out_image, px, vec4(1.0, 0.0, 1.0, 0.0));
  }
}
