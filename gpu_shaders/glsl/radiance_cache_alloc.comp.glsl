#include "radiance_cache_layout_lib.glsl"
/* Radiance cache, per clipmap cell: a cell marked this frame (a screen probe interpolates its
 * probe) without a probe takes the next free slot (rc_counter[1] counts them; past the free
 * list's length rc_counter[0] it gets none and the rays there trace on). The new slot records its
 * world cell and level and is flagged never traced (rc_state_io.x = 0: new probes are traced
 * first). Images rc_cells_io, rc_slots_io, rc_state_io, rc_counter; samplers rc_marks, rc_free.
 */
void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(rc_cells_io);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  if (texelFetch(rc_marks, tx, 0).x != float(rc_frame + 1) || imageLoad(rc_cells_io, tx).x > 0.5) {
    return;
  }
  int k;
  ivec3 cell = rc_texel_cell(tx, k);
  int i = imageAtomicAdd(rc_counter, ivec2(1, 0), 1);
  if (i >= imageLoad(rc_counter, ivec2(0, 0)).x) {
    return;                                  /* the cache is full */
  }
  int slot = int(texelFetch(rc_free, rc_slot_texel(i), 0).x + 0.5);
  imageStore(rc_cells_io, tx, vec4(float(slot + 1)));
  imageStore(rc_slots_io, rc_slot_texel(slot), vec4(vec3(cell), float(k + 1)));
  imageStore(rc_state_io, rc_slot_texel(slot), vec4(0.0));
}
