/* Lumen GI: a mip chain packed in one 2D texture (hzb.py's pyramids: the SSGI depth HZB and the
 * cone-filtered scene colour). Blender 5.0's GPUTexture has no mip levels a compute pass can bind
 * as an image, so the levels sit side by side: level 0 (the image, base size) at (0, 0), level
 * k >= 1 to its right at x = base.x, stacked downwards from y = 0. Level k is ceil(level k-1 / 2)
 * per side, so texel c of level k covers exactly the pixels [c 2^k, (c + 1) 2^k) of level 0
 * (clipped to the image): a texel's children are 2c and 2c + 1 of the level below, where they
 * exist. numpy twin: hzb.mip_layout.
 */
#ifndef LUMEN_MIP_LIB
#define LUMEN_MIP_LIB

int mip_count(ivec2 base)
{
  int n = 1;
  ivec2 s = base;
  while (s.x > 1 || s.y > 1) {
    s = (s + 1) / 2;
    n++;
  }
  return n;
}

/* Offset and size in the atlas of mip `level` of an image of size `base`. */
void mip_rect(int level, ivec2 base, out ivec2 off, out ivec2 size)
{
  off = ivec2(0);
  size = base;
  if (level <= 0) {
    return;
  }
  off = ivec2(base.x, 0);
  size = (base + 1) / 2;
  for (int k = 1; k < level; k++) {
    off.y += size.y;
    size = (size + 1) / 2;
  }
}

#endif /* LUMEN_MIP_LIB */
