/* Lumen GI G-buffer: one draw per texture group (world-space vertices, no index buffer).
 * Vertex inputs: pos, nor (world), uv (the corner's UV, zero without a UV map), albedo, emit (per
 * corner, the triangle's material values; with an emission texture emit is the strength).
 * Push constants: view_proj, use_albedo_tex, use_emit_tex. Samplers: albedo_tex, emit_tex (RGBA32F,
 * row 0 = v 0), read with texelFetch and filtered here: bilinear, texel centres at (i + 0.5) / size,
 * wrapping (repeat), exactly as lumen_addon.materials.sample_texture. The sampler state cannot be
 * set from Python in Blender 5.0 (GPUTexture has no filter / extend mode), so no hardware filtering.
 * Outputs (colour attachments 0..3, RGBA32F):
 *   out_position: world position xyz, w = 1 where a surface was drawn (0: background)
 *   out_normal:   world normal xyz (interpolated, normalised), w = 1
 *   out_albedo:   base colour rgb (linear; the texture replaces it), w = 1
 *   out_emission: emission colour x strength rgb (texture x strength), w = 1
 * The vertex and fragment stages are separated by the marker line "// FRAGMENT" (without the space).
 */
void main()
{
  v_pos = pos;
  v_nor = nor;
  v_uv = uv;
  v_albedo = albedo;
  v_emit = emit;
  gl_Position = view_proj * vec4(pos, 1.0);
}
//FRAGMENT
ivec2 wrap_texel(ivec2 i, ivec2 size)
{
  return ((i % size) + size) % size;
}

vec3 sample_bilinear(sampler2D tex, vec2 uv)
{
  ivec2 size = textureSize(tex, 0);
  vec2 x = uv * vec2(size) - 0.5;
  vec2 x0 = floor(x);
  vec2 f = x - x0;
  ivec2 i0 = ivec2(x0);
  vec3 c00 = texelFetch(tex, wrap_texel(i0, size), 0).rgb;
  vec3 c10 = texelFetch(tex, wrap_texel(i0 + ivec2(1, 0), size), 0).rgb;
  vec3 c01 = texelFetch(tex, wrap_texel(i0 + ivec2(0, 1), size), 0).rgb;
  vec3 c11 = texelFetch(tex, wrap_texel(i0 + ivec2(1, 1), size), 0).rgb;
  return mix(mix(c00, c10, f.x), mix(c01, c11, f.x), f.y);
}

void main()
{
  out_position = vec4(v_pos, 1.0);
  vec3 n = v_nor;
  float len = length(n);
  out_normal = vec4(len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0), 1.0);
  vec3 albedo = use_albedo_tex != 0 ? sample_bilinear(albedo_tex, v_uv) : v_albedo;
  vec3 emit = use_emit_tex != 0 ? sample_bilinear(emit_tex, v_uv) * v_emit : v_emit;
  out_albedo = vec4(albedo, 1.0);
  out_emission = vec4(emit, 1.0);
}
