#include "octahedral_lib.glsl"
/* The shading normal of pixel px: a normal map's (Cycles' Normal Map node), else the interpolated
 * normal. gbuffer.glsl packs it into the albedo and emission attachments' w (octahedral u, v:
 * gbuf_normal keeps the geometric normal, which every plane, shell and cone test wants).
 * Only when the G-buffer packed them (`stored`: a drawn mesh has a normal map, the pass says);
 * else `n`, read nothing. Needs the samplers gbuf_albedo and gbuf_emission. */
vec3 gbuf_shading_normal(ivec2 px, vec3 n, bool stored)
{
  if (!stored) {
    return n;
  }
  return oct_decode(vec2(texelFetch(gbuf_albedo, px, 0).w, texelFetch(gbuf_emission, px, 0).w));
}
