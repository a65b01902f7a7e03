#include "radiance_cache_layout_lib.glsl"
/* Radiance cache, per probe slot: keep the probe of a cell that screen probes used within the
 * last rc_keep frames and that is still inside its clipmap; free the others (rc_reset: all, the
 * scene changed) and list every free slot (rc_free_out, appended with rc_counter[0]) for
 * radiance_cache_alloc. Images: rc_slots_io (xyz world cell, w level + 1; 0 free), rc_cells_io
 * (cell -> slot + 1), rc_free_out, rc_counter (R32I). Sampler rc_marks (frame + 1 of the last mark).
 */
void main()
{
  ivec2 st = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(rc_slots_io);
  if (st.x >= size.x || st.y >= size.y) {
    return;
  }
  int slot = st.x + RC_SLOT_W * st.y;
  vec4 s = imageLoad(rc_slots_io, st);
  if (s.w > 0.5) {
    int k = int(s.w + 0.5) - 1;
    ivec3 cell = ivec3(floor(s.xyz + 0.5));
    ivec2 ct = rc_cell_texel(k, cell);
    ivec3 o = rc_origin(k);
    bool inside = all(greaterThanEqual(cell, o)) && all(lessThan(cell, o + RC_N));
    float mark = texelFetch(rc_marks, ct, 0).x;
    bool used = mark > 0.5 && float(rc_frame + 1) - mark <= float(rc_keep);
    if (rc_reset == 0 && inside && used) {
      return;
    }
    if (int(imageLoad(rc_cells_io, ct).x + 0.5) == slot + 1) {
      imageStore(rc_cells_io, ct, vec4(0.0));
    }
    imageStore(rc_slots_io, st, vec4(0.0));
  }
  int i = imageAtomicAdd(rc_counter, ivec2(0, 0), 1);
  imageStore(rc_free_out, rc_slot_texel(i), vec4(float(slot)));
}
