/* Lumen GI: sample sequences and direction warps (probe ray jitter, cosine rays, hashes).
 * numpy twin: gpu_shaders/probe_math.py (same names).
 *
 *   float radical_inverse_vdc(uint bits)  Van der Corput: the bits reversed as a binary fraction,
 *                                         truncated to 24 bits (float(rev >> 8) / 2^24): every value
 *                                         is exact in float32 and < 1 (a 32-bit fraction would round
 *                                         up to 1.0 near the top), so CPU and GPU agree bit for bit.
 *   vec2  hammersley(uint i, uint n)      (i / n, vdc(i)): point i of an n-point Hammersley set
 *                                         (bit-exact against numpy; i / n is exact when n is a
 *                                         power of two, the usual probe ray count).
 *   uint  pcg_hash(uint v)                PCG-RXS-M-XS 32-bit hash (one LCG step + output permutation),
 *                                         a good per-pixel / per-frame seed scrambler.
 *   mat3  tangent_frame(vec3 n)           orthonormal columns (t, b, n) for a unit n, branch-free in
 *                                         the pole direction (Duff et al. 2017): no singularity at
 *                                         any n, including n = (0, 0, +-1).
 *   vec3  cosine_hemisphere(vec2 u, vec3 n)  u in [0,1)^2 -> unit direction around unit n with
 *                                         pdf = dot(d, n) / pi (Malley: a uniform disk lifted).
 *   vec3  uniform_sphere(vec2 u)          u in [0,1)^2 -> unit direction, pdf = 1 / (4 pi).
 */
#ifndef LUMEN_SAMPLING_LIB
#define LUMEN_SAMPLING_LIB

#define SAMPLING_TWO_PI 6.28318530717958648

float radical_inverse_vdc(uint bits)
{
  return float(bitfieldReverse(bits) >> 8u) * (1.0 / 16777216.0);
}

vec2 hammersley(uint i, uint n)
{
  return vec2(float(i) / float(n), radical_inverse_vdc(i));
}

uint pcg_hash(uint v)
{
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

mat3 tangent_frame(vec3 n)
{
  float s = n.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (s + n.z);
  float b = n.x * n.y * a;
  vec3 t = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
  vec3 bt = vec3(b, s + n.y * n.y * a, -n.y);
  return mat3(t, bt, n);
}

vec3 cosine_hemisphere(vec2 u, vec3 n)
{
  float r = sqrt(u.x);
  float phi = SAMPLING_TWO_PI * u.y;
  vec3 local = vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.x)));
  return tangent_frame(n) * local;
}

vec3 uniform_sphere(vec2 u)
{
  float z = 1.0 - 2.0 * u.x;
  float r = sqrt(max(0.0, 1.0 - z * z));
  float phi = SAMPLING_TWO_PI * u.y;
  return vec3(r * cos(phi), r * sin(phi), z);
}

#endif /* LUMEN_SAMPLING_LIB */
