#include "global_sdf_lib.glsl"
#include "camera_lib.glsl"
#include "gi_trace_lib.glsl"
/* Debug view of the GI rays: one gi_trace (gi_trace_lib.glsl) per camera ray, the tracer every GI
 * pass uses. Output out_image: (hit distance or -1, 1 when the hit came from the global-SDF part
 * (t >= GSDF_MESH_SPLIT, then refined on a mesh), hit object, 0).
 * Push constants: inv_view_proj, t_max.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 ro, rd;
  camera_ray(px, size, ro, rd);
  float t;
  int obj;
  if (gi_trace(ro, rd, t_max, t, obj)) {
    imageStore(out_image, px, vec4(t, t >= GSDF_MESH_SPLIT ? 1.0 : 0.0, float(obj), 0.0));
  }
  else {
    imageStore(out_image, px, vec4(-1.0, 0.0, -1.0, 0.0));
  }
}
