#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_trace_lib.glsl"
#include "radiance_cache_mark_lib.glsl"
/* Screen probes, the pixels no probe serves (split from screen_probe_integrate, which lists them
 * in fb_list: (px, voxel) per slot, fb_counter slots): FALLBACK_RAYS cosine rays per listed pixel
 * from its surface, added to what integrate wrote there (its near emission, w = 0). The same rays,
 * seeds and sums as when integrate traced them itself, so the same image; but one invocation per
 * listed pixel, so the work groups are full (traced in integrate, each 8x8 group waited on its
 * slowest pixel: 68 -> 1810 ms from 10 to 1,000 small objects in the earlier measurement).
 * With the world radiance cache on the rays trace ~2 m and take the far field from it
 * (rc_radiance), marking the cells around the pixel for the next frame's probes (rc_marks).
 * Dispatched over the listed pixels (their count read back: compute.read_counter); slots past
 * fb_counter return.
 * Budget: at most fb_budget rays in all (the uniform probes' count). A longer list (thousands of
 * pixels on many small objects: no probe lies on a sphere 4 pixels wide) traces m = 8, 4, 2 or 1
 * rays per pixel, the strata phase, phase + 16 / m, ... of the 16 on turn phase of each cycle of
 * 16 / m of the pixel's turns (fb_turn: the frame / the viewport's split, whose pixels are
 * integrated one redraw in `split`; the rotation held for the cycle): the temporal mix of one
 * cycle averages exactly the 16 strata, so the frame's cost stays the screen's, not the scene's.
 * Inputs: gbuf_position, gbuf_normal, fb_list, fb_counter, the tracers (mesh and global SDF,
 * surface cache, sky, voxel lighting), the radiance cache's samplers; cam_pos, frame, t_max,
 * rc_camera, fb_budget, fb_turn; image out_image (read and written), rc_marks.
 */
#define FALLBACK_RAYS 16

void main()
{
  ivec2 lsize = imageSize(fb_list);
  int slot = int(gl_GlobalInvocationID.x);
  int count = imageLoad(fb_counter, ivec2(0, 0)).x;
  if (slot >= count || slot >= lsize.x * lsize.y) {
    return;
  }
  int m = FALLBACK_RAYS;
  while (m > 1 && count * m > fb_budget) {
    m >>= 1;
  }
  int period = FALLBACK_RAYS / m;
  vec4 entry = imageLoad(fb_list, ivec2(slot % lsize.x, slot / lsize.x));
  ivec2 px = ivec2(entry.xy);
  float voxel = entry.z;
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    return;
  }
  uint seed = pcg_hash(uint(px.x) + 7919u * uint(px.y))
              ^ pcg_hash(uint(fb_turn / period) + 0x2545f491u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 o = p + n * max(voxel, 1e-3);
  vec3 sum = vec3(0.0);
  int k = rc_level(o);
  bool mark = false;
  for (int i = fb_turn % period; i < FALLBACK_RAYS; i += period) {
    vec3 dir = cosine_hemisphere(fract(hammersley(uint(i), uint(FALLBACK_RAYS)) + rot), n);
    float t;
    int status;
    sum += rc_radiance(o, dir, t_max, k, t, status);
    mark = mark || status > 0;
  }
  if (mark) {
    rc_mark(o, k, frame);     /* probes for this pixel's next frames */
  }
  vec3 near = imageLoad(out_image, px).rgb;
  imageStore(out_image, px, vec4(3.14159265358979 * sum / float(m) + near, 0.0));
}
