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
 * A list longer than the budget even at 1 ray a pixel (1,000 small objects at 512 px: 18,000
 * listed pixels a redraw against 8,192 rays), in the viewport from the second round since the
 * history's reset (fb_round >= 1; screen_probe_temporal_split keeps a pixel's history on a
 * turn without a sample): skip is the least power of 2 (at most FALLBACK_SKIP_MAX) that brings
 * the rays under the budget, and a pixel traces on the turns where (turn + the hash of its 4x4
 * block) % skip == 0, once in `skip` turns; on the others it writes w = -2 (no sample).
 * Blocks, not pixels: llvmpipe runs a work group's lanes together, and a lane that traces
 * holds up the others (that scene, skip 4: the pass 248 ms at every pixel, 122 ms hashed per
 * pixel, 111 by 4x4 block, 101 by 8x8 block; 170 by windows of consecutive list slots, which
 * cluster the costly pixels). Not in the first round (no history to keep yet) nor in F12
 * (fb_round -1: every pixel every frame). The viewport applies the same skip in integrate too
 * (fb_skip, from the last redraw's list: a pixel off its turn is not listed), so this pass's
 * groups hold only pixels that trace (a group of 64 list slots spans a few 4x4 blocks, and one
 * tracing block held it up: 1,000 spheres at 256 px, this pass 46.9 -> 27.7 ms a redraw); the
 * rule here then finds the list within budget. Why: the pass's cost stays near the budget's, a
 * screen-size cost, not the scene's; such pixels converge `skip` times slower (that scene's
 * viewport against its own 128th redraw, relMSE at 16 / 64 redraws: 0.0067 / 0.0035 without,
 * 0.0068 / 0.0043 with; its redraw 875 -> 734 ms).
 * Inputs: gbuf_position, gbuf_normal, fb_list, fb_counter, the tracers (mesh and global SDF,
 * surface cache, sky, voxel lighting), the radiance cache's samplers; cam_pos, frame, t_max,
 * rc_camera, fb_budget, fb_turn, fb_round; image out_image (read and written), rc_marks.
 */
#define FALLBACK_RAYS 16
#define FALLBACK_SKIP_MAX 16

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
  int skip = 1;
  while (fb_round >= 1 && skip < FALLBACK_SKIP_MAX && count > fb_budget * skip) {
    skip <<= 1;
  }
  ivec2 block = px >> 2;
  if (skip > 1 && (fb_turn + int(pcg_hash(uint(block.x) + 7919u * uint(block.y)) % uint(skip)))
                  % skip != 0) {
    imageStore(out_image, px, vec4(imageLoad(out_image, px).rgb, -2.0));
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
