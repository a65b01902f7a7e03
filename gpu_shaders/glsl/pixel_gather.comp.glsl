#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "surface_cache_lib.glsl"
#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "gi_trace_lib.glsl"
/* Reference final gather (tests and the "brute force" check of the screen probes): per G-buffer
 * pixel, `rays` cosine-distributed rays (a Hammersley set rotated per pixel and frame) through
 * gi_trace_lib.glsl, E = pi * mean(L): the same rays and surface cache as the probes, without
 * the probes' interpolation, filtering and SH; plus sc_near_emission (emitters nearer the surface
 * than the rays' origin), as the probes' integrate pass adds it.
 * Inputs: gbuf_position, gbuf_normal; cam_pos, rays, frame, t_max.
 * Output out_image: E.rgb, w = 1 on surface pixels, -1 on the background.
 */
#define PI 3.14159265358979

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
  float h;
  int obj;
  sdf_scene(p, h, obj);
  vec3 o = p + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  uint seed = pcg_hash(uint(px.x) + 7919u * uint(px.y)) ^ pcg_hash(uint(frame) + 0x2545f491u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 sum = vec3(0.0);
  for (int i = 0; i < rays; i++) {
    vec3 dir = cosine_hemisphere(fract(hammersley(uint(i), uint(rays)) + rot), n);
    float t, w;
    sum += gi_radiance(o, dir, t_max, t, w);
  }
  vec3 near = sc_near_emission(p, n, gi_object_voxel(max(obj, 0)));   /* under the rays' origin */
  imageStore(out_image, px, vec4(PI * sum / float(rays) + near, 1.0));
}
