/* Screen probes: the list of the atlas's live probe slots, so that the tracing passes run one
 * invocation per ray of a live probe and none for the empty slots (the atlas holds the 8x8 and
 * 4x4 adaptive levels for the worst case, 28 slots per uniform probe: a 128 px F12 placed ~220
 * probes in 7,168 slots). Why it matters: on llvmpipe an invocation of a large shader costs
 * about as much when it returns at once as when it traces (measured, cornell F12 128 px, a
 * per-dispatch timer: the probe trace over the whole atlas cost 1.3-1.9 s per frame with no
 * probe at all against ~1.9 s with them; wrapping the body in a loop no lane enters did not
 * help). On a GPU the empty invocations are cheap but not free.
 * Per slot (i, j) of the atlas (one invocation): a live slot (probe_info w > 0) is appended to
 * probe_list (RGBA32F: i, j; index from the atomic counter probe_counter, cleared before); an
 * empty one gets w -1 (no probe) in the texels a trace would have written this dispatch (every
 * texel_step-th from texel_phase: screen_probe_trace_lib.glsl's split).
 * Inputs: probe_info; push probe_res, texel_step, texel_phase. Images: probe_list,
 * probe_counter (R32I), out_image (the probe radiance atlas).
 */
void main()
{
  ivec2 slot = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(probe_info, 0);
  if (slot.x >= size.x || slot.y >= size.y) {
    return;
  }
  if (texelFetch(probe_info, slot, 0).w > 0.0) {
    int e = imageAtomicAdd(probe_counter, ivec2(0, 0), 1);
    ivec2 lsize = imageSize(probe_list);
    imageStore(probe_list, ivec2(e % lsize.x, e / lsize.x), vec4(vec2(slot), 0.0, 0.0));
    return;
  }
  int side = probe_res / texel_step;
  for (int k = 0; k < side * side; k++) {
    ivec2 tx = slot * probe_res + ivec2(k % side, k / side) * texel_step + texel_phase;
    imageStore(out_image, tx, vec4(0.0, 0.0, 0.0, -1.0));
  }
}
