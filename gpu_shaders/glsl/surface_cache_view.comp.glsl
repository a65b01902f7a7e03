#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "surface_cache_lib.glsl"
#include "gbuffer_lib.glsl"
/* Surface cache seen from the camera (debug views and tests): per G-buffer pixel, the object whose
 * SDF is nearest to the pixel's world point, the pixel's normal in that object's local space, and
 * sc_sample_local of whatever lighting-atlas texture is bound as sc_final (final light, or a
 * surface_cache_layer.comp.glsl view of albedo, normal, direct light, card colours).
 * Inputs: gbuf_position, gbuf_normal; cam_pos. Output out_image: rgb, w = card weight (0: no card
 * sees this point, shown magenta so holes in the cards stand out); background: black, w = -1.
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
  float h;
  int obj;
  sdf_scene(p, h, obj);
  mat4 w2l = sc_object_w2l(obj);
  vec3 pl = (w2l * vec4(p, 1.0)).xyz;
  vec3 nl = normalize(transpose(inverse(mat3(w2l))) * n);
  float weight;
  vec3 v = sc_sample_local(obj, pl, nl, sdf_object_texel(obj, 4).w, inverse(w2l),
                           gi_object_voxel(obj), weight);
  imageStore(out_image, px, weight > 0.0 ? vec4(v, weight) : vec4(1.0, 0.0, 1.0, 0.0));
}
