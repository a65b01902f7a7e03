#include "radiance_cache_layout_lib.glsl"
/* Radiance cache, per probe slot: this frame's trace list under the budget rc_cap (entries
 * appended with rc_counter[2]). Phase 0: the probes never traced (new first); phase 1: traced
 * probes in the round-robin window [rc_cursor, rc_cursor + rc_window) of slots, while the list
 * has room (the window moves on by rc_window every frame, so the least recently re-traced go
 * next: a still camera re-traces at most rc_window probes a frame).
 * Output rc_list_out: x slot (-1: none), y 1 for a new probe. Samplers rc_slots, rc_state.
 */
void main()
{
  ivec2 st = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(rc_slots, 0);
  if (st.x >= size.x || st.y >= size.y) {
    return;
  }
  int slot = st.x + RC_SLOT_W * st.y;
  int slots = size.x * size.y;
  if (texelFetch(rc_slots, st, 0).w < 0.5) {
    return;
  }
  bool fresh = texelFetch(rc_state, st, 0).x < 0.5;
  if (rc_phase == 0 ? !fresh : (fresh || ((slot - rc_cursor) % slots + slots) % slots >= rc_window)) {
    return;
  }
  int i = imageAtomicAdd(rc_counter, ivec2(2, 0), 1);
  if (i < rc_cap) {
    imageStore(rc_list_out, rc_slot_texel(i), vec4(float(slot), fresh ? 1.0 : 0.0, 0.0, 0.0));
  }
}
