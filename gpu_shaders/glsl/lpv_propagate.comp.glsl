#include "lpv_lib.glsl"
/* LPV propagation, one iteration (lpv.py; lecture 21, "Radiance Propagation"; Kaplanyan and
 * Dachsbacher 2010's face-based scheme), gathered per destination cell d from its 6 neighbours
 * s = d - dir. The light s sends towards each of the 5 faces of d that do not face s passes the
 * face's centre in direction w (the front face: w = dir, a side face of normal f:
 * w = (dir + f / 2) / sqrt(1.25)), flux Phi_f = dOmega_f I_s(w). The paper's solid angles
 * (0.4006696846 front, 0.4234413544 side) add up to 4 pi (1 + 1.9e-5) over the 30 faces: scaled
 * here to 4 pi exactly, so with no clamp (the operator stays linear) every iteration moves exactly
 * the flux it takes, 2 sqrt(pi) c0 summed over the grid, less what leaves the grid or is blocked
 * (the paper's constants gained 1.5e-4 in 8 iterations). The face's flux becomes a Lambertian
 * emitter in d, Phi_f / pi x lpv_lobe(w): a cosine lobe along the direction it crossed the face.
 * (The paper orients it along the face normal f; along w the light keeps its direction: the
 * wall-to-floor bounce of tests/gpu/test_lpv.py reached 1.02 of the integral in 32 iterations,
 * 0.61 along f, whose sideways lobes make the light diffuse rather than travel.) T: the
 * geometry pass's transmittance of the crossing s -> d.
 * Inputs src_r, src_g, src_b (last iteration), geometry; push grid_dims, first.
 * Outputs out_r, out_g, out_b (this iteration's light) and acc_r, acc_g, acc_b (READ | WRITE:
 * the sum of every iteration; first = 1 starts it from src, the injected light, + this one).
 */
void main()
{
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec3 dims = grid_dims.xyz;
  if (t.x >= dims.x || t.y >= dims.y * dims.z) {
    return;
  }
  ivec3 d = lpv_cell(t, dims);
  vec4 r = vec4(0.0), g = vec4(0.0), b = vec4(0.0);
  for (int k = 0; k < 6; k++) {
    int a = k / 2;
    ivec3 dir = ivec3(0);
    dir[a] = (k % 2 == 0) ? 1 : -1;
    ivec3 s = d - dir;
    if (!lpv_inside(s, dims)) {
      continue;
    }
    float T = texelFetch(geometry, lpv_texel(min(s, d), dims), 0)[a];
    if (T <= 0.0) {
      continue;
    }
    ivec2 st = lpv_texel(s, dims);
    vec4 cr = texelFetch(src_r, st, 0);
    vec4 cg = texelFetch(src_g, st, 0);
    vec4 cb = texelFetch(src_b, st, 0);
    vec3 dv = vec3(dir);
    for (int f = 0; f < 5; f++) {
      vec3 nf = dv;
      vec3 w = dv;
      float omega = 0.4006620325557998;
      if (f > 0) {
        nf = vec3(0.0);
        nf[(a + 1 + (f - 1) / 2) % 3] = ((f - 1) % 2 == 0) ? 1.0 : -1.0;
        w = (dv + 0.5 * nf) * 0.894427190999916;
        omega = 0.42343326745934884;
      }
      vec4 y = lpv_basis(w);
      vec4 lobe = lpv_lobe(w) * (T * omega / LPV_PI);
      r += dot(cr, y) * lobe;
      g += dot(cg, y) * lobe;
      b += dot(cb, y) * lobe;
    }
  }
  imageStore(out_r, t, r);
  imageStore(out_g, t, g);
  imageStore(out_b, t, b);
  vec4 ar = first != 0 ? texelFetch(src_r, t, 0) : imageLoad(acc_r, t);
  vec4 ag = first != 0 ? texelFetch(src_g, t, 0) : imageLoad(acc_g, t);
  vec4 ab = first != 0 ? texelFetch(src_b, t, 0) : imageLoad(acc_b, t);
  imageStore(acc_r, t, ar + r);
  imageStore(acc_g, t, ag + g);
  imageStore(acc_b, t, ab + b);
}
