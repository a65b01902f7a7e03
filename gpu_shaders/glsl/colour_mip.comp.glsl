#include "mip_lib.glsl"
/* Scene colour pyramid (hzb.py, SSGI's cone-filtered radiance): level 0 (level = 0) is the
 * source image premultiplied by surface coverage (rgb x a, a = 1 on a surface, 0 on the
 * background: rays never hit the background, so the sky must not bleed into a cone's average);
 * level k >= 1 the mean of its children (2x2, or fewer at an odd edge), still premultiplied, so a
 * lookup divides by a. Push: level, base. Inputs: source (the lit image), gbuf_position (level 0
 * only). Output: colour (RGBA32F atlas, READ | WRITE).
 */
void main()
{
  ivec2 c = ivec2(gl_GlobalInvocationID.xy);
  ivec2 off, size;
  mip_rect(level, base, off, size);
  if (c.x >= size.x || c.y >= size.y) {
    return;
  }
  if (level == 0) {
    float a = texelFetch(gbuf_position, c, 0).w >= 0.5 ? 1.0 : 0.0;
    imageStore(colour, c, vec4(texelFetch(source, c, 0).rgb * a, a));
    return;
  }
  ivec2 src_off, src_size;
  mip_rect(level - 1, base, src_off, src_size);
  vec4 sum = vec4(0.0);
  float n = 0.0;
  for (int j = 0; j < 2; j++) {
    for (int i = 0; i < 2; i++) {
      ivec2 s = 2 * c + ivec2(i, j);
      if (s.x < src_size.x && s.y < src_size.y) {
        sum += imageLoad(colour, src_off + s);
        n += 1.0;
      }
    }
  }
  imageStore(colour, off + c, sum / max(n, 1.0));
}
