#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
/* Lumen GI: the surface cache (mesh cards) on the GPU (needs sdf_lib.glsl, sdf_ray_lib.glsl).
 *
 * Resources (declared by surface_cache.SurfaceCache.declare, layout in card_packing.py):
 *   sampler2D sc_cards       RGBA32F, 4 texels per (instance, card) row   (row tables:
 *   sampler2D sc_instances   RGBA32F, 1 texel per object-table row:        row_table_lib.glsl)
 *                            (first card row, count, emissive cards)
 *   sampler2D sc_albedo      card atlas: albedo.rgb, opacity      (mesh-local layers, shared by
 *   sampler2D sc_normal      card atlas: local normal.xyz, depth   all instances of a mesh)
 *   sampler2D sc_emissive    card atlas: emissive.rgb
 *   sampler2D sc_final       lighting atlas: final radiance (direct + indirect) * albedo / pi
 *                            + emissive, one texel per (instance, card) texel
 * Card look directions as lumen_addon.cards.AXES (+X -X +Y -Y +Z -Z); a card looking along A
 * spans local axes PLANE[A] and its texel (i, j) centre is rect_min + (i + 0.5, j + 0.5) * texel.
 */

#define SC_CARD_TEXELS 4

const vec3 SC_AXES[6] = vec3[6](vec3(1.0, 0.0, 0.0), vec3(-1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0),
                                vec3(0.0, -1.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, -1.0));

ivec2 sc_plane(int axis)
{
  return axis < 2 ? ivec2(1, 2) : (axis < 4 ? ivec2(0, 2) : ivec2(0, 1));
}

vec4 sc_card(int row, int t)
{
  return texelFetch(sc_cards, row_texel(row, t, SC_CARD_TEXELS), 0);
}

ivec2 sc_instance_range(int obj)
{
  vec4 r = texelFetch(sc_instances, row_texel(obj, 0, 1), 0);
  return ivec2(r.xy + 0.5);
}

/* World-to-local matrix of object obj (the object table's first three rows). */
mat4 sc_object_w2l(int obj)
{
  return transpose(mat4(sdf_object_texel(obj, 0), sdf_object_texel(obj, 1),
                        sdf_object_texel(obj, 2), vec4(0.0, 0.0, 0.0, 1.0)));
}

/* Surface of texel ij (0..w-1, 0..h-1) of card row `row`, in the mesh's local space; false where
 * the card saw nothing. */
bool sc_texel_surface(int row, ivec2 ij, out vec3 p, out vec3 n, out vec3 albedo, out vec3 emissive)
{
  vec4 t0 = sc_card(row, 0);
  vec4 t1 = sc_card(row, 1);
  vec4 t2 = sc_card(row, 2);
  vec4 t3 = sc_card(row, 3);
  int axis = int(t0.y + 0.5);
  ivec2 at = ivec2(t1.xy + 0.5) + ij;
  vec4 a = texelFetch(sc_albedo, at, 0);
  vec4 nd = texelFetch(sc_normal, at, 0);
  albedo = a.rgb;
  emissive = texelFetch(sc_emissive, at, 0).rgb;
  n = nd.xyz;
  vec2 uv = t2.xy + (vec2(ij) + 0.5) * (t2.zw - t2.xy) / t1.zw;
  ivec2 pl = sc_plane(axis);
  p = vec3(0.0);
  p[pl.x] = uv.x;
  p[pl.y] = uv.y;
  p += SC_AXES[axis] * (t3.x + nd.w);
  return a.a > 0.5;
}

/* Gradient normal of object obj's mesh SDF at local point p (central differences, e local m). */
vec3 sdf_mesh_normal_local(int obj, vec3 p, float e)
{
  vec3 g = vec3(0.0);
  for (int k = 0; k < 6; k++) {      /* one call site (see gi_scene_gradients) */
    int axis = k >> 1;
    float s = (k & 1) == 0 ? 1.0 : -1.0;
    vec3 q = p;
    q[axis] += s * e;
    g[axis] += s * sdf_mesh_local(obj, q);
  }
  float l = length(g);
  return l > 0.0 ? g / l : vec3(0.0, 0.0, 1.0);
}

/* Final lighting of object obj's surface cache at local point p with local unit normal n: every
 * card facing n (weight = cos between n and the card's view, above 0.1) that holds p at its depth
 * (bilinear over the 2x2 texels around p, texels kept when opaque and within `tol` + the slope of
 * the surface across a texel of p's depth) contributes; weight returns the sum of the card
 * weights (0: no card sees p, the result is then black).
 * guard (ray hits): with a local-to-world matrix l2w and world voxel guard_voxel > 0, a texel that
 * a wall hides from p (gi_visible between the two lifted points) is left out: card texels are
 * coarser than a thin wall, and a lit texel outside must not bleed into the dark room inside
 * (the field at p's lifted end, `room`, is sampled once for all of them: gi_visible_from).
 * A guarded card reads one texel, the nearest to p that the test passes (the nearest, then its
 * neighbour along x, along y, the diagonal), testing no more than that: rays integrate many hits, so
 * point sampling where a surface is near changes no image (bench/quality.py to 4 digits, thin's
 * leak 0.21 -> 0.20%), while four tests a card made a floor's hits among 1,000 spheres cost more
 * than their rays (a floor's texels are coarse, so every hit near a sphere was guarded):
 * bench/glsl_ab.py --objects 1000 frame 0.87x, 10 objects 0.98x. */
vec3 sc_sample_local(int obj, vec3 p, vec3 n, float tol, mat4 l2w, float guard_voxel, out float weight)
{
  vec3 pw = (l2w * vec4(p, 1.0)).xyz;
  vec3 nw = normalize(transpose(inverse(mat3(l2w))) * n);
  /* Room around p (lifted as gi_visible lifts it): a wall between p and a texel of its 2x2
   * footprint lies within two texels of it, so with more room than that no texel is tested. */
  float room = 1e30;
  vec3 lifted = gi_lifted(pw, nw, guard_voxel);
  if (guard_voxel > 0.0) {
    float hh;
    int oo;
    room = sdf_scene(lifted, hh, oo);     /* also gi_visible's field at p's end */
  }
  vec4 ga = vec4(0.0);                    /* and its gradient, once needed */
  float scale = sdf_object_texel(obj, 7).w;
  ivec2 range = sc_instance_range(obj);
  vec3 sum = vec3(0.0);
  weight = 0.0;
  for (int r = range.x; r < range.x + range.y; r++) {
    vec4 t0 = sc_card(r, 0);
    int axis = int(t0.y + 0.5);
    float facing = -dot(n, SC_AXES[axis]);
    if (facing < 0.1) {
      continue;
    }
    vec4 t1 = sc_card(r, 1);
    vec4 t2 = sc_card(r, 2);
    vec4 t3 = sc_card(r, 3);
    ivec2 pl = sc_plane(axis);
    vec2 res = t1.zw;
    vec2 ts = (t2.zw - t2.xy) / res;
    vec2 f = (vec2(p[pl.x], p[pl.y]) - t2.xy) / ts - 0.5;
    if (any(lessThan(f, vec2(-1.0))) || any(greaterThan(f, res))) {
      continue;
    }
    float depth = dot(SC_AXES[axis], p) - t3.x;
    float tan_s = sqrt(max(1.0 - facing * facing, 0.0)) / facing;
    float dtol = tol + max(ts.x, ts.y) * (0.5 + 1.5 * min(tan_s, 20.0));
    ivec2 i0 = ivec2(floor(f));
    vec2 w = f - vec2(i0);
    ivec2 hi = ivec2(res + 0.5) - 1;
    vec3 csum = vec3(0.0);
    float cw = 0.0;
    bool guard = guard_voxel > 0.0
                 && room < 2.0 * max(ts.x, ts.y) * scale + GI_HIT_VOXELS * guard_voxel;
    /* guarded: the nearest texel the wall test passes, alone (see above) */
    int first = int(w.x >= 0.5) + 2 * int(w.y >= 0.5);
    for (int j = 0; j < 4; j++) {
      int k = j ^ first;         /* the nearest first */
      if (guard && j > 0 && cw > 0.0) {
        break;                   /* an earlier one passed */
      }
      ivec2 d = ivec2(k & 1, k >> 1);
      ivec2 ij = clamp(i0 + d, ivec2(0), hi);
      ivec2 at = ivec2(t1.xy + 0.5) + ij;
      float op = texelFetch(sc_albedo, at, 0).a;
      float td = texelFetch(sc_normal, at, 0).w;
      if (op < 0.5 || abs(td - depth) > dtol) {
        continue;
      }
      if (guard) {
        vec3 q = vec3(0.0);
        vec2 uv = t2.xy + (vec2(ij) + 0.5) * ts;
        q[pl.x] = uv.x;
        q[pl.y] = uv.y;
        q += SC_AXES[axis] * (t3.x + td);
        if (!gi_visible_from(lifted, room, (l2w * vec4(q, 1.0)).xyz, nw, guard_voxel, ga)) {
          continue;
        }
      }
      float bw = (d.x == 1 ? w.x : 1.0 - w.x) * (d.y == 1 ? w.y : 1.0 - w.y) + 1e-4;
      csum += bw * texelFetch(sc_final, ivec2(t0.zw + 0.5) + ij, 0).rgb;
      cw += bw;
    }
    if (cw > 0.0) {
      sum += facing * csum / cw;
      weight += facing;
    }
  }
  return weight > 0.0 ? sum / weight : vec3(0.0);
}

/* Final lighting at world point pw on object obj, hit by a ray along dir: local point, SDF
 * gradient normal, then sc_sample_local with the texel guard. (Turning the normal to face the
 * ray was measured worse: 3.4% leak in bench/quality.py's thin room against 1.2%.) The object's voxel sets the depth tolerance (the SDF surface lies within about half a
 * voxel of the mesh). */
vec3 sc_sample_world(int obj, vec3 pw, vec3 dir, out float weight)
{
  vec3 pl = sdf_world_to_local(obj, pw);
  float h = sdf_object_texel(obj, 4).w;
  vec3 nl = sdf_mesh_normal_local(obj, pl, 0.5 * h);
  mat4 w2l = sc_object_w2l(obj);
  return sc_sample_local(obj, pl, nl, 1.0 * h, inverse(w2l), gi_object_voxel(obj), weight);
}

/* Emission that reaches world point p (unit normal n, object voxel `voxel`) from emissive card
 * texels facing it from less than SC_NEAR_VOXELS voxels above its surface (0 < (q - p).n <
 * 1.5 voxel), as irradiance: each texel a patch parallel to its card, its irradiance at p by
 * Lambert's polygon formula (exact at any distance, card texels being coarser than the gap),
 * weighted 1 up to one voxel (the rays' origin) and fading to 0 at 1.5 (there the rays' half-voxel
 * hit shell sees it: at a hard 1.5, test_gi's emitting closed room, whose corners have emitters
 * within the slab, rose from 0.988 to 1.025 of its closed form 0.999).
 * Why: the GI rays leave a surface one voxel off it, and the thin-wall rule closes any gap under
 * a voxel, so an emitter closer than that to a surface (a light panel under a ceiling, a lamp
 * against a wall) lights nothing there: in bench/quality.py's glow room the ceiling's halo around
 * the panel, 61% of the missing light. This slab is what no ray reaches (rays start above it):
 * here it is summed from the cards, unoccluded (nothing thinner than a voxel is resolved there).
 * Candidates are the instances listed in p's object-grid cell whose bounding sphere comes within
 * reach, then only their emissive cards (card texel 3 z > 0, surface_cache.py), within a window
 * of 4 x reach around p's projection (beyond it a plane at the slab's height holds under 6% of a
 * receiver's view), sampled every `step` texels so that a side has at most 2 SC_NEAR_WINDOW + 1
 * samples. */
#define SC_NEAR_VOXELS 1.5
#define SC_NEAR_WINDOW 8
vec3 sc_near_emission(vec3 p, vec3 n, float voxel)
{
  vec3 E = vec3(0.0);
  float reach = SC_NEAR_VOXELS * voxel;
  vec4 g0 = sdf_grid_texel(0);
  vec4 g1 = sdf_grid_texel(1);
  ivec3 dims = ivec3(g1.xyz + 0.5);
  vec3 cq = clamp(p, g0.xyz, g0.xyz + vec3(dims) * g0.w);
  ivec3 c = clamp(ivec3(floor((cq - g0.xyz) / g0.w)), ivec3(0), dims - 1);
  vec4 cell = sdf_grid_texel(3 + c.x + dims.x * (c.y + dims.y * c.z));
  int count = int(round(cell.y));
  bool listed = count >= 0;
  int total = listed ? count : sdf_object_count();
  int first = int(cell.x + 0.5);
  int list = int(g1.w + 0.5);
  for (int k = 0; k < total; k++) {
    int i = k;
    if (listed) {
      int e = first + k;
      vec4 pair = sdf_grid_texel(list + (e >> 1));
      vec2 entry = (e & 1) == 0 ? pair.xy : pair.zw;
      if (entry.y > reach) {
        break;                    /* nearest first: the rest are farther still */
      }
      i = int(entry.x + 0.5);
    }
    vec4 range4 = texelFetch(sc_instances, row_texel(i, 0, 1), 0);
    if (range4.z < 0.5 || sdf_object_texel(i, 9).z >= 1.0) {
      continue;                   /* none of its cards emits, or diffuse rays do not see it */
    }
    vec4 sphere = sdf_object_texel(i, 8);
    if (length(p - sphere.xyz) - sphere.w > reach) {
      continue;
    }
    mat4 w2l = sc_object_w2l(i);
    mat4 l2w = inverse(w2l);
    mat3 nrm = transpose(mat3(w2l));
    float scale = sdf_object_texel(i, 7).w;
    vec3 pl = (w2l * vec4(p, 1.0)).xyz;
    ivec2 range = ivec2(range4.xy + 0.5);
    for (int r = range.x; r < range.x + range.y; r++) {
      vec4 t3 = sc_card(r, 3);
      if (t3.z <= 0.0) {
        continue;                 /* no emissive texel on this card */
      }
      vec4 t0 = sc_card(r, 0);
      vec4 t1 = sc_card(r, 1);
      vec4 t2 = sc_card(r, 2);
      int axis = int(t0.y + 0.5);
      ivec2 pl2 = sc_plane(axis);
      vec2 res = t1.zw;
      vec2 ts = (t2.zw - t2.xy) / res;
      vec2 f = (vec2(pl[pl2.x], pl[pl2.y]) - t2.xy) / ts - 0.5;
      /* 4 x reach around p, at most SC_NEAR_WINDOW samples either side: a stride of
       * `step` texels, each sample standing for step^2 texels */
      ivec2 want = ivec2(ceil(4.0 * reach / (scale * ts)));
      ivec2 step = max((want + SC_NEAR_WINDOW - 1) / SC_NEAR_WINDOW, ivec2(1));
      ivec2 ires = ivec2(res + 0.5);
      ivec2 c0 = clamp(ivec2(floor(f + 0.5)), ivec2(0), ires - 1);
      ivec2 lo = c0 - step * ((c0 - max(c0 - want, ivec2(0))) / step);
      ivec2 hi = min(c0 + want, ires - 1);
      if (any(greaterThan(abs(f - vec2(c0)), vec2(want + 1)))) {
        continue;                 /* p's projection is off this card by more than the window */
      }
      for (int y = lo.y; y <= hi.y; y += step.y) {
        for (int x = lo.x; x <= hi.x; x += step.x) {
          ivec2 at = ivec2(t1.xy + 0.5) + ivec2(x, y);
          vec3 Le = texelFetch(sc_emissive, at, 0).rgb;
          if (max(Le.r, max(Le.g, Le.b)) <= 0.0 || texelFetch(sc_albedo, at, 0).a < 0.5) {
            continue;
          }
          vec4 nd = texelFetch(sc_normal, at, 0);
          float depth = t3.x + nd.w;
          vec3 q = vec3(0.0);
          vec2 uv = t2.xy + (vec2(x, y) + 0.5) * ts;
          q[pl2.x] = uv.x;
          q[pl2.y] = uv.y;
          q += SC_AXES[axis] * depth;
          vec3 d = (l2w * vec4(q, 1.0)).xyz - p;
          float hgt = dot(n, d);
          if (hgt <= 0.05 * voxel || hgt >= reach || dot(nrm * nd.xyz, d) >= 0.0) {
            continue;             /* outside the slab, or p behind the emitting side */
          }
          /* the sample's patch (step x step texels, parallel to the card) as a polygon, its
           * irradiance by Lambert's formula E = Le / 2 sum_k angle_k (n . unit(v_k x v_k+1)):
           * exact however near p (a point estimate was 24% low 1.5 cm beside a 4.6 cm texel) */
          vec2 a = t2.xy + vec2(x, y) * ts;
          vec2 b = min(a + vec2(step) * ts, t2.zw);
          vec3 v[4];
          for (int k = 0; k < 4; k++) {
            vec3 c = vec3(0.0);
            c[pl2.x] = (k == 1 || k == 2) ? b.x : a.x;
            c[pl2.y] = k >= 2 ? b.y : a.y;
            c += SC_AXES[axis] * depth;
            v[k] = normalize((l2w * vec4(c, 1.0)).xyz - p);
          }
          float sum = 0.0;
          for (int k = 0; k < 4; k++) {
            vec3 g = cross(v[k], v[(k + 1) & 3]);
            float len = length(g);
            if (len > 1e-8) {
              sum += acos(clamp(dot(v[k], v[(k + 1) & 3]), -1.0, 1.0)) * dot(n, g / len);
            }
          }
          /* full weight up to the rays' origin (a voxel up), fading out over the half voxel
           * above it, where the rays' thin-wall shell begins to see it */
          E += Le * (0.5 * abs(sum) * clamp((reach - hgt) / ((SC_NEAR_VOXELS - 1.0) * voxel), 0.0, 1.0));
        }
      }
    }
  }
  return E;
}
