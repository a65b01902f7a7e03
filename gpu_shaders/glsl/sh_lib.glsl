/* Lumen GI: real spherical harmonics up to band 2 (probe radiance -> 2-band / 3rd order SH).
 * numpy twin: gpu_shaders/probe_math.py (sh*).
 *
 * Normalisation: the standard orthonormal real SH (as Cycles and most engines use, no
 * Condon-Shortley sign), for a unit direction d = (x, y, z). Coefficient order is i = l*(l+1) + m:
 *   0: Y00  = 0.282095                  (1/2 sqrt(1/pi))
 *   1: Y1-1 = 0.488603 y    2: Y10 = 0.488603 z    3: Y11 = 0.488603 x     (sqrt(3/(4pi)))
 *   4: Y2-2 = 1.092548 xy   5: Y2-1 = 1.092548 yz  6: Y20 = 0.315392 (3z^2 - 1)
 *   7: Y21  = 1.092548 xz   8: Y22  = 0.546274 (x^2 - y^2)
 * (constants below to full float precision so that the integrals are exact, e.g. 4pi Y00^2 = 1).
 * sh4 = bands 0-1 (4 coefficients), sh9 = bands 0-2 (9 coefficients).
 *
 *   void sh4_basis(vec3 d, out float b[4]), void sh9_basis(vec3 d, out float b[9])
 *   vec3 sh9_eval(vec3 c[9], vec3 d)            radiance reconstruction sum_i c_i Y_i(d)
 *   vec3 sh4_irradiance(vec3 c[4], vec3 n), vec3 sh9_irradiance(vec3 c[9], vec3 n)
 *        irradiance E(n) = integral L(d) max(0, n.d) dd from the RADIANCE coefficients c (RGB):
 *        sum_i A_l(i) c_i Y_i(n), clamped-cosine convolution A0 = pi, A1 = 2pi/3, A2 = pi/4
 *        (Funk-Hecke), so a constant radiance L gives E = pi L. Divide by pi for the diffuse
 *        outgoing radiance of a white Lambert surface.
 * Array parameters ("out float b[9]", "vec3 c[9]") compile as-is in Blender's GLSL 4.3 on llvmpipe.
 */
#ifndef LUMEN_SH_LIB
#define LUMEN_SH_LIB

#define SH_Y0 0.28209479177387814
#define SH_Y1 0.4886025119029199
#define SH_Y2 1.0925484305920792
#define SH_Y20 0.31539156525252005
#define SH_Y22 0.5462742152960396
#define SH_A0 3.14159265358979
#define SH_A1 2.0943951023931953
#define SH_A2 0.7853981633974483

void sh4_basis(vec3 d, out float b[4])
{
  b[0] = SH_Y0;
  b[1] = SH_Y1 * d.y;
  b[2] = SH_Y1 * d.z;
  b[3] = SH_Y1 * d.x;
}

void sh9_basis(vec3 d, out float b[9])
{
  b[0] = SH_Y0;
  b[1] = SH_Y1 * d.y;
  b[2] = SH_Y1 * d.z;
  b[3] = SH_Y1 * d.x;
  b[4] = SH_Y2 * d.x * d.y;
  b[5] = SH_Y2 * d.y * d.z;
  b[6] = SH_Y20 * (3.0 * d.z * d.z - 1.0);
  b[7] = SH_Y2 * d.x * d.z;
  b[8] = SH_Y22 * (d.x * d.x - d.y * d.y);
}

vec3 sh9_eval(vec3 c[9], vec3 d)
{
  float b[9];
  sh9_basis(d, b);
  vec3 r = vec3(0.0);
  for (int i = 0; i < 9; i++) {
    r += c[i] * b[i];
  }
  return r;
}

vec3 sh4_irradiance(vec3 c[4], vec3 n)
{
  float b[4];
  sh4_basis(n, b);
  return SH_A0 * c[0] * b[0] + SH_A1 * (c[1] * b[1] + c[2] * b[2] + c[3] * b[3]);
}

vec3 sh9_irradiance(vec3 c[9], vec3 n)
{
  float b[9];
  sh9_basis(n, b);
  vec3 band1 = c[1] * b[1] + c[2] * b[2] + c[3] * b[3];
  vec3 band2 = c[4] * b[4] + c[5] * b[5] + c[6] * b[6] + c[7] * b[7] + c[8] * b[8];
  return SH_A0 * c[0] * b[0] + SH_A1 * band1 + SH_A2 * band2;
}

#endif /* LUMEN_SH_LIB */
