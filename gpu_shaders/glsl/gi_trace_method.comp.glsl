#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Debug view TRACE_METHOD (the lecture's picture in "Speed of Different Tracing Methods"): per
 * G-buffer pixel, `rays` cosine rays from where a screen probe there would start them, each
 * through lumen_trace_lib.glsl exactly as the probes trace; the share served by the screen trace
 * (red), the mesh SDFs (green), the global SDF (blue); rays that meet nothing (the sky) add no
 * colour. Inputs: gbuf_position, gbuf_normal (screen_trace.SAMPLERS); push rays, frame, t_max.
 * Output out_image: rgb shares, w 1 (0 on the background).
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, screen_cam.xyz, p, n)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  float h;
  int obj;
  sdf_scene(p, h, obj);
  vec3 o = p + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  uint seed = pcg_hash(uint(px.x) + uint(px.y) * 65536u + uint(frame) * 40503u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 counts = vec3(0.0);
  for (int k = 0; k < rays; k++) {
    vec3 dir = cosine_hemisphere(fract(hammersley(uint(k), uint(rays)) + rot), n);
    float t;
    int kind;
    lumen_radiance(o, dir, t_max, t, kind);
    counts += vec3(kind == LUMEN_SCREEN, kind == LUMEN_MESH, kind == LUMEN_GLOBAL);
  }
  imageStore(out_image, px, vec4(counts / float(max(rays, 1)), 1.0));
}
