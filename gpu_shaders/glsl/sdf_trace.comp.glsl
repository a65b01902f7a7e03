#include "sdf_lib.glsl"
#include "camera_lib.glsl"
/* Lumen GI: one sphere-traced ray per pixel through the scene SDF (needs sdf_lib.glsl).
 *
 * Push constants: inv_view_proj (NDC -> world), t_max (metres along the ray), max_steps.
 * The ray of pixel (x, y) (row 0 at the bottom, as Blender's render result) runs from the
 * unprojected NDC point (u, v, -1) towards (u, v, +1), u/v at the pixel centre; t is measured
 * from that near-plane point. Output trace_out (RG32F): (hit distance or -1 on a miss, steps).
 * Stepping as MeshSDF.sphere_trace: hit when d <= 0.05 voxel, else advance by max(d, 0.1 voxel);
 * the voxel is that of the nearest object.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(trace_out);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 ro, rd;
  camera_ray(px, size, ro, rd);

  float t = 0.0;
  float hit = -1.0;
  int steps = 0;
  while (steps < max_steps) {
    float h;
    int nearest;
    float d = sdf_scene(ro + t * rd, h, nearest);
    steps++;
    if (d <= 0.05 * h) {
      hit = t;
      break;
    }
    t += max(d, 0.1 * h);
    if (t > t_max) {
      break;
    }
  }
  imageStore(trace_out, px, vec4(hit, float(steps), 0.0, 0.0));
}
