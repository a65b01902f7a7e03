/* Lumen GI: screen probes' occlusion maps (written by screen_probe_occlusion.comp.glsl, read by
 * screen_probe_integrate): per uniform probe, PROBE_OCC_TEXELS texels in a row of the sampler
 * probe_occ: texels 0-3 hold the free distance (metres, from the probe's lifted end, the
 * thin-wall rule) along 16 azimuths of its tangent plane (azimuth k = k * 2 pi / 16 from u
 * towards v, probe_occ_basis; texel k / 4, channel k % 4); texel 4 (voxel, field at the lifted
 * end, reach, 1), w 0 where there is no map. */
#ifndef LUMEN_PROBE_OCC_LIB
#define LUMEN_PROBE_OCC_LIB

#define PROBE_OCC_TEXELS 5
#define PROBE_OCC_AZIMUTHS 16
#define PROBE_OCC_STEP (6.28318530718 / float(PROBE_OCC_AZIMUTHS))

void probe_occ_basis(vec3 n, out vec3 u, out vec3 v)
{
  vec3 a = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  u = normalize(cross(n, a));
  v = cross(n, u);
}

#endif /* LUMEN_PROBE_OCC_LIB */
