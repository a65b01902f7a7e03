/* Lumen GI G-buffer: one draw per texture group (world-space vertices, no index buffer).
 * Vertex inputs: pos, nor (world), uv (the corner's UV, zero without a UV map), albedo, emit (per
 * corner, the triangle's material values; with an emission texture emit is the strength), tan
 * (world tangent xyz and the bitangent's sign: a normal map's, zero without one).
 * Push constants: view_proj, use_albedo_tex, alpha_clip (a cut-out: discard where the albedo
 * texture's alpha is under 0.5), use_emit_tex, albedo_base_h, emit_base_h (the base
 * level's height), footprint_scale (the share of the pixel's texture footprint one G-buffer
 * filters: 1, or 1 / sqrt(n) for one of n anti-aliasing samples), use_normal_tex (1 a
 * tangent-space normal map, as Cycles' Normal Map node; 2 a Bump node's height: the shading
 * normal), normal_base_h, normal_strength, pack_shading (1 when a drawn mesh has a normal map or a bump: only then are shading
 * normals packed, and read: gbuffer_shading_lib.glsl). Samplers: albedo_tex, normal_tex,
 * emit_tex (RGBA32F: gbuffer.mip_chain, the levels stacked in rows, row 0 = v 0), read with texelFetch and filtered here: anisotropic trilinear over the mip
 * levels of the pixel's UV footprint, each bilinear with texel centres at (i + 0.5) / size and
 * wrapping (repeat); at level 0 exactly lumen_addon.materials.sample_texture. The sampler state
 * cannot be set from Python in Blender 5.0 (GPUTexture has no filter / extend mode, no mipmaps).
 * Outputs (colour attachments 0..3, RGBA32F):
 *   out_position: world position xyz, w = 1 where a surface was drawn (0: background; 0.25: a
 *                 holdout, v_holdout or group_holdout (a Holdout shader), whose other
 *                 attachments are 0: every pass takes w < 0.5
 *                 for background, and the composites write rgba 0 where w > 0.125)
 *   out_normal:   world normal xyz (interpolated, normalised), w = 1
 *   out_normal:   the interpolated (geometric) normal; planes, shells and cones use it
 *   out_albedo:   base colour rgb (linear; the texture replaces it), w = the shading normal's
 *                 octahedral u (a normal map's, else the interpolated normal;
 *                 gbuffer_shading_lib.glsl) with pack_shading, else 1
 *   out_emission: emission colour x strength rgb (texture x strength), w = its octahedral v
 *                 with pack_shading, else 1
 * The vertex and fragment stages are separated by the marker line "// FRAGMENT" (without the space).
 */
void main()
{
  v_pos = pos;
  v_nor = nor;
  v_uv = uv;
  v_tan = tan;
  v_albedo = albedo;
  v_emit = emit;
  v_holdout = 0.0;
  gl_Position = view_proj * vec4(pos, 1.0);
}
//FRAGMENT
ivec2 wrap_texel(ivec2 i, ivec2 size)
{
  return ((i % size) + size) % size;
}

/* Bilinear in one mip level: `size` texels at row offset `y0` of the stacked chain. */
vec4 sample_level(sampler2D tex, vec2 uv, ivec2 size, int y0)
{
  vec2 x = uv * vec2(size) - 0.5;
  vec2 x0 = floor(x);
  vec2 f = x - x0;
  ivec2 i0 = ivec2(x0);
  ivec2 o = ivec2(0, y0);
  vec4 c00 = texelFetch(tex, o + wrap_texel(i0, size), 0);
  vec4 c10 = texelFetch(tex, o + wrap_texel(i0 + ivec2(1, 0), size), 0);
  vec4 c01 = texelFetch(tex, o + wrap_texel(i0 + ivec2(0, 1), size), 0);
  vec4 c11 = texelFetch(tex, o + wrap_texel(i0 + ivec2(1, 1), size), 0);
  return mix(mix(c00, c10, f.x), mix(c01, c11, f.x), f.y);
}

/* Anisotropic trilinear filtering over the stacked mip chain, as hardware anisotropic filtering
 * does: the pixel's UV footprint (the two screen-axis derivatives in base texels, times
 * footprint_scale) is covered by up to MAX_ANISO trilinear taps along its longer axis, each
 * at the level of the shorter one (the longer / taps). Why: a level from the longer axis alone
 * blurs a floor seen at a grazing angle into its mean colour (the `textured` benchmark's far
 * floor lost its bricks). footprint_scale < 1 when the G-buffer is one of n anti-aliasing
 * samples (1 / sqrt(n): the samples together cover the pixel, each its share), so the pixel
 * filter of the samples' mean is not blurred again by a whole pixel's mip footprint. */
#define MAX_ANISO 16
vec4 sample_mipmapped(sampler2D tex, vec2 uv, int base_h)
{
  int w = textureSize(tex, 0).x;
  ivec2 base = ivec2(w, base_h);
  vec2 du = dFdx(uv) * footprint_scale;
  vec2 dv = dFdy(uv) * footprint_scale;
  vec2 dx = du * vec2(base);
  vec2 dy = dv * vec2(base);
  float lx = length(dx), ly = length(dy);
  float major = max(lx, ly), minor = min(lx, ly);
  int taps = int(clamp(ceil(major / max(minor, 1e-6)), 1.0, float(MAX_ANISO)));
  vec2 axis = lx >= ly ? du : dv;
  float lod = max(log2(max(major / float(taps), 1e-6)), 0.0);
  int top = 0;
  for (int m = max(w, base_h); m > 1; m >>= 1) {
    top++;
  }
  lod = min(lod, float(top));
  int l0 = int(floor(lod));
  int l1 = min(l0 + 1, top);
  int y = 0;
  ivec2 s = base;
  for (int k = 0; k < l0; k++) {
    y += s.y;
    s = max(s / 2, ivec2(1));
  }
  bool two = !(l1 == l0 || lod == float(l0));
  vec4 sum = vec4(0.0);
  for (int i = 0; i < taps; i++) {
    vec2 t = uv + axis * ((float(i) + 0.5) / float(taps) - 0.5);
    vec4 a = sample_level(tex, t, s, y);
    if (two) {
      a = mix(a, sample_level(tex, t, max(s / 2, ivec2(1)), y + s.y), lod - float(l0));
    }
    sum += a;
  }
  return sum / float(taps);
}

/* octahedral_lib.glsl's oct_encode (the fragment stage has no includes): the shading normal
 * packed into the albedo and emission w (gbuffer_shading_lib.glsl decodes it) */
vec2 gbuf_oct_encode(vec3 d)
{
  vec3 p = d / (abs(d.x) + abs(d.y) + abs(d.z));
  vec2 f = p.xy;
  if (p.z < 0.0) {
    f = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
  }
  return f * 0.5 + 0.5;
}

/* Cycles' Normal Map node (tangent space): the map's colour c as 2c - 1 in the frame of the
 * interpolated tangent (made orthogonal to n), sign x n x t and n; Strength s blends from n:
 * normalize(n + (N - n) s). */
vec3 normal_mapped(vec3 n, vec3 c)
{
  vec3 t = v_tan.xyz - n * dot(n, v_tan.xyz);
  float tl = length(t);
  if (tl <= 0.0) {
    return n;                           /* no tangent (no UVs there): the geometric normal */
  }
  t /= tl;
  vec3 b = (v_tan.w < 0.0 ? -1.0 : 1.0) * cross(n, t);
  vec3 m = 2.0 * c - 1.0;
  vec3 N = normalize(m.x * t + m.y * b + m.z * n);
  if (normal_strength != 1.0) {
    N = normalize(n + (N - n) * max(normal_strength, 0.0));
  }
  return N;
}

/* Cycles' Bump node (surface gradient, Mikkelsen 2010): h the height times Distance at this
 * pixel, its change to the neighbouring pixels (the screen derivatives, where Cycles takes its
 * ray differentials) against the position's; Strength s blends from n: normalize(s N + (1 - s)
 * n). A derivative is constant over a 2x2 pixel quad, as EEVEE's bump. */
vec3 bumped(vec3 n, float h)
{
  vec3 dpdx = dFdx(v_pos);
  vec3 dpdy = dFdy(v_pos);
  vec3 rx = cross(dpdy, n);
  vec3 ry = cross(n, dpdx);
  float det = dot(dpdx, rx);
  vec3 grad = dFdx(h) * rx + dFdy(h) * ry;
  vec3 N = abs(det) * n - (det < 0.0 ? -1.0 : 1.0) * grad;
  float len = length(N);
  if (!(len > 0.0)) {
    return n;
  }
  N /= len;
  float s = clamp(normal_strength, 0.0, 1.0);
  return normalize(s * N + (1.0 - s) * n);
}

void main()
{
  if (v_holdout > 0.5 || group_holdout != 0) {
    /* a holdout (Cycles, EEVEE; the object's flag, or a Holdout shader's material: group_holdout):
     * what the camera sees there is nothing, not even the world;
     * its depth still hides what lies behind it */
    out_position = vec4(v_pos, 0.25);
    out_normal = vec4(0.0);
    out_albedo = vec4(0.0);
    out_emission = vec4(0.0);
    return;
  }
  vec4 base = use_albedo_tex != 0 ? sample_mipmapped(albedo_tex, v_uv, albedo_base_h)
                                  : vec4(v_albedo, 1.0);
  vec3 emit = use_emit_tex != 0 ? sample_mipmapped(emit_tex, v_uv, emit_base_h).rgb * v_emit
                                : v_emit;
  /* a cut-out's alpha from the base level: a mip level's mean alpha moves the coverage with the
   * distance (one-texel holes seen minified: 79% drawn instead of half, tests/gpu/
   * test_cut_outs.py); the base level keeps it (the anti-aliasing samples average the edges) */
  if (alpha_clip != 0 && use_albedo_tex != 0
      && sample_level(albedo_tex, v_uv, ivec2(textureSize(albedo_tex, 0).x, albedo_base_h), 0).a
             < 0.5) {
    discard;                 /* a cut-out's hole (Material.alpha_clip): what is behind shows */
  }
  out_position = vec4(v_pos, 1.0);
  vec3 n = v_nor;
  float len = length(n);
  n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
  vec2 oct = vec2(1.0);
  if (pack_shading != 0) {     /* some drawn mesh has a normal map: every pixel packs its own */
    vec3 ns = n;
    if (use_normal_tex != 0) {
      vec4 m = sample_mipmapped(normal_tex, v_uv, normal_base_h);
      ns = use_normal_tex == 2 ? bumped(n, m.r) : normal_mapped(n, m.rgb);
    }
    oct = gbuf_oct_encode(ns);
  }
  out_normal = vec4(n, 1.0);
  out_albedo = vec4(base.rgb, oct.x);
  out_emission = vec4(emit, oct.y);
}
