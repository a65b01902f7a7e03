/* Lumen GI: octahedral mapping of the unit sphere onto [0,1]^2 (screen probes, radiance cache).
 * numpy twin: gpu_shaders/probe_math.py (oct_*).
 *
 *   vec2  oct_encode(vec3 d)        direction (any length > 0) -> uv in [0,1]^2. p = d / |d|_1; the
 *                                   lower hemisphere (p.z < 0) is folded over the diagonals:
 *                                   p.xy = (1 - |p.yx|) * sign(p.xy), then uv = p.xy * 0.5 + 0.5.
 *                                   sign(0) counts as +1 here (GLSL sign(0) = 0 would send -z to the
 *                                   +z pole), so -z maps to uv (1, 1).
 *   vec3  oct_decode(vec2 uv)       the exact inverse, normalised.
 *   vec3  oct_texel_dir(ivec2 texel, int res, vec2 jitter)
 *                                   direction through uv = (texel + jitter) / res of a res x res
 *                                   probe, jitter in [0,1)^2 (0.5, 0.5: the texel centre).
 *   ivec2 oct_texel(vec3 d, int res)  the texel containing d (clamped to [0, res - 1]).
 *   float oct_texel_solid_angle(ivec2 texel, int res)
 *                                   EXACT for even res (what probes use): in each of the 8
 *                                   octahedron faces the map uv -> octahedron point is affine and
 *                                   for even res the face boundaries (the axes and the diagonals
 *                                   |x| + |y| = 1 in [-1,1]^2) run along texel edges or texel
 *                                   diagonals. So a texel is two triangles, each inside one face,
 *                                   whose images are planar octahedron triangles; their radial
 *                                   projections are spherical triangles (straight segments project
 *                                   to great-circle arcs), measured with Van Oosterom-Strackee.
 *                                   For odd res the middle row / column straddles an axis fold and
 *                                   the same formula is an approximation there.
 */
#ifndef LUMEN_OCTAHEDRAL_LIB
#define LUMEN_OCTAHEDRAL_LIB

vec2 oct_sign_not_zero(vec2 v)
{
  return vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
}

vec2 oct_encode(vec3 d)
{
  vec3 p = d / (abs(d.x) + abs(d.y) + abs(d.z));
  vec2 f = p.xy;
  if (p.z < 0.0) {
    f = (1.0 - abs(p.yx)) * oct_sign_not_zero(p.xy);
  }
  return f * 0.5 + 0.5;
}

vec3 oct_decode(vec2 uv)
{
  vec2 f = uv * 2.0 - 1.0;
  vec3 n = vec3(f, 1.0 - abs(f.x) - abs(f.y));
  float t = max(-n.z, 0.0);
  n.xy -= oct_sign_not_zero(n.xy) * t;
  return normalize(n);
}

vec3 oct_texel_dir(ivec2 texel, int res, vec2 jitter)
{
  return oct_decode((vec2(texel) + jitter) / float(res));
}

ivec2 oct_texel(vec3 d, int res)
{
  return clamp(ivec2(floor(oct_encode(d) * float(res))), ivec2(0), ivec2(res - 1));
}

/* Solid angle of the spherical triangle of unit vectors a, b, c (Van Oosterom-Strackee). The triple
 * product is taken on the edge vectors: same value, far less cancellation for small triangles. */
float oct_triangle_solid_angle(vec3 a, vec3 b, vec3 c)
{
  float num = abs(dot(a, cross(b - a, c - a)));
  float den = 1.0 + dot(a, b) + dot(b, c) + dot(c, a);
  return 2.0 * atan(num, den);
}

float oct_texel_solid_angle(ivec2 texel, int res)
{
  float r = float(res);
  vec2 t = vec2(texel);
  vec3 c00 = oct_decode(t / r);
  vec3 c10 = oct_decode((t + vec2(1.0, 0.0)) / r);
  vec3 c01 = oct_decode((t + vec2(0.0, 1.0)) / r);
  vec3 c11 = oct_decode((t + vec2(1.0, 1.0)) / r);
  vec2 centre = (t + 0.5) / r * 2.0 - 1.0;
  if (centre.x * centre.y > 0.0) {
    /* quadrants ++ and --: the fold |x| + |y| = 1 runs along the texel's 10-01 diagonal */
    return oct_triangle_solid_angle(c10, c01, c00) + oct_triangle_solid_angle(c10, c11, c01);
  }
  /* quadrants +- and -+: the fold runs along the 00-11 diagonal */
  return oct_triangle_solid_angle(c00, c10, c11) + oct_triangle_solid_angle(c00, c11, c01);
}

#endif /* LUMEN_OCTAHEDRAL_LIB */
