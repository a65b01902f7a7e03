#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "screen_trace_lib.glsl"
/* SSGI trace (ssgi.py; lecture 21, "Radiance Sampling in Screen Space", "Hierachical Tracing"):
 * `rays` rays per G-buffer pixel in the cosine hemisphere of its normal (stratified Hammersley
 * points, rotated per pixel and frame), each walked through the HZB by screen_trace_lib.glsl
 * (at most max_steps cells; the lecture: 50).
 * Inputs: gbuf_position, gbuf_normal, hzb; push view_proj, cam_tmax (camera position xyz, w the
 * world length of a ray), counts (rays per pixel, frame, max_steps), thickness (packed so: Blender
 * counts scalars after a vec3 so that the plain list passed 128 bytes).
 * Output out_image [width x rays, height]: ray k of pixel p at (p.x * rays + k, p.y) =
 *   (world direction xyz, w): w >= 0 hit at that distance; -1 left the screen (or reached t_max /
 *   the far plane); -2 out of steps; -3 no surface at the pixel.
 */
#define SSGI_NONE -3.0

void main()
{
  vec3 cam_pos = cam_tmax.xyz;
  float t_max = cam_tmax.w;
  int rays = counts.x;
  int frame = counts.y;
  int max_steps = counts.z;
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 out_size = imageSize(out_image);
  if (gid.x >= out_size.x || gid.y >= out_size.y) {
    return;
  }
  ivec2 px = ivec2(gid.x / rays, gid.y);
  int k = gid.x - px.x * rays;
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, gid, vec4(0.0, 0.0, 1.0, SSGI_NONE));
    return;
  }
  uint seed = pcg_hash(uint(px.x) + uint(px.y) * 65536u + uint(frame) * 40503u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 dir = cosine_hemisphere(fract(hammersley(uint(k), uint(rays)) + rot), n);

  /* start a hair off the surface (relative to its distance: the depth's precision is too) */
  vec3 o = p + n * (1e-4 * distance(p, cam_pos) + 1e-4);
  float t_free;
  ivec2 hit_px;
  float result = screen_trace(view_proj, cam_pos, o, dir, t_max, max_steps, thickness, 0.0, false,
                              false, t_free, hit_px);
  imageStore(out_image, gid, vec4(dir, result));
}
