#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "gbuffer_lib.glsl"
/* Anti-aliasing, one jittered sample (antialias.py): the indirect irradiance at this sample's
 * surface points, from the frame's E (computed once on the unjittered G-buffer). Each pixel
 * takes the unjittered pixels of its 3x3 neighbourhood that show the same surface (normals
 * within ~40 degrees, the sample's point within a few pixel footprints of their plane),
 * weighted by a tent of radius one pixel around where the sample lies (pixel centre + jitter);
 * if none qualifies (a surface only this sample sees), the one whose point is nearest. A pixel
 * behind a wall from the sample's point (sdf_ray_lib.glsl's gi_visible, the thin-wall rule
 * included) does not qualify: a floor and the ground outside its room are one plane, and with
 * jitters across Cycles' 3 px filter the room's floor by a 1.5 cm wall took the sunlit ground's
 * light. The field at the sample's lifted point is sampled once for its neighbours' tests
 * (gi_visible_from).
 * Inputs: gbuf_position, gbuf_normal (this sample's G-buffer), base_position, base_normal,
 * e_base (the frame's); push jitter (pixels), footprint (a, b: a pixel's footprint at distance d
 * is a d + b), cam_pos. Output out_image: E (rgb), w 1 (0 on the background).
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
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  float tol = 2.0 * (footprint.x * distance(p, cam_pos) + footprint.y);
  float voxel, room;                           /* room: the field at p's lifted end */
  vec3 lifted = gi_lifted_end(p, n, voxel, room);
  vec4 ga = vec4(0.0);                         /* and its gradient, once a test needs it */
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  vec3 nearest = vec3(0.0);
  float best = 1e30;
  for (int dy = -1; dy <= 1; dy++) {
    for (int dx = -1; dx <= 1; dx++) {
      ivec2 q = px + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) {
        continue;
      }
      vec4 bp = texelFetch(base_position, q, 0);
      if (bp.w < 0.5) {
        continue;
      }
      vec3 bn = normalize(texelFetch(base_normal, q, 0).xyz);
      if (dot(bn, cam_pos - bp.xyz) < 0.0) {
        bn = -bn;
      }
      vec3 e = texelFetch(e_base, q, 0).rgb;
      float d = distance(bp.xyz, p);
      if (d < best) {
        best = d;
        nearest = e;
      }
      float plane = abs(dot(p - bp.xyz, bn));
      if (dot(bn, n) < 0.75 || plane > tol) {
        continue;
      }
      vec2 off = vec2(dx, dy) - jitter;
      float w = max(1.0 - abs(off.x), 0.0) * max(1.0 - abs(off.y), 0.0);
      if (w <= 0.0) {
        continue;
      }
      if (!gi_visible_from(lifted, room, bp.xyz, bn, voxel, ga)) {
        continue;
      }
      sum += w * e;
      wsum += w;
    }
  }
  imageStore(out_image, px, vec4(wsum > 1e-6 ? sum / wsum : nearest, 1.0));
}
