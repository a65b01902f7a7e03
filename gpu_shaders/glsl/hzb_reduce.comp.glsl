#include "mip_lib.glsl"
/* HZB level `level` from level - 1 (hzb.py): each texel the MIN of its children's window depths
 * (2x2, or fewer at an odd edge), the nearest surface in its cell. The lecture's "min-depth
 * mipmap": a ray segment whose depth stays below a cell's min is in front of everything the cell
 * shows, so the trace skips the whole cell (and climbs a level). One dispatch per level over the
 * destination texels, reading and writing the same atlas image (hzb, READ | WRITE).
 * Push: level, base (level 0's size).
 */
void main()
{
  ivec2 c = ivec2(gl_GlobalInvocationID.xy);
  ivec2 off, size, src_off, src_size;
  mip_rect(level, base, off, size);
  if (c.x >= size.x || c.y >= size.y) {
    return;
  }
  mip_rect(level - 1, base, src_off, src_size);
  float z = 1.0;
  for (int j = 0; j < 2; j++) {
    for (int i = 0; i < 2; i++) {
      ivec2 s = 2 * c + ivec2(i, j);
      if (s.x < src_size.x && s.y < src_size.y) {
        z = min(z, imageLoad(hzb, src_off + s).x);
      }
    }
  }
  imageStore(hzb, off + c, vec4(z, 0.0, 0.0, 0.0));
}
