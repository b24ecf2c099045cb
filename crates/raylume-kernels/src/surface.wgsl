// What a ray sees (surface.rs): the surface at a hit, albedo textures, the environment, and
// the offset of the next ray's origin (a rounding-error bound). Reads the global bindings.

struct SurfaceHit {
    position: vec3<f32>,
    geometric_normal: vec3<f32>,
    shading_normal: vec3<f32>,
    uv: vec2<f32>,
    material: u32,
    offset: f32,
    back_offset: f32,
}

fn surface_at(hit: Hit, origin: vec3<f32>, dir: vec3<f32>) -> SurfaceHit {
    let prim = bvh_primitives[hit.prim];
    let material = prim_materials[hit.prim];
    let a = prim.a.xyz;
//#if spheres
    if (HAS_SPHERES && bitcast<u32>(prim.b.w) == PRIM_SPHERE) {
        let radius = prim.a.w;
        let p = origin + dir * hit.t;
        let from_center = p - a;
        let n = normalize(from_center);
        let position = a + n * radius;
        let magnitude = abs(a) + vec3<f32>(radius);
        let offset = hit_offset(n, magnitude, 2.0 * radius, 1.0);
        return SurfaceHit(position, n, n, direction_to_equirect(n), material, offset, back_offset(magnitude, hit.t));
    }
//#endif
    let b = prim.b.xyz;
    let c = prim.c.xyz;
    let w = 1.0 - hit.u - hit.v;
    let position = a * w + b * hit.u + c * hit.v;
    let cr = cross(b - a, c - a);
    let ng = normalize(cr);
    let span = max(a, max(b, c)) - min(a, min(b, c));
    let extent = max(span.x, max(span.y, span.z));
    let magnitude = max(abs(a), max(abs(b), abs(c)));
    let offset = hit_offset(ng, magnitude, extent, extent * extent / length(cr));
    var ns = ng;
    var uv = vec2<f32>(hit.u, hit.v);
//#if shading_normals|textures
    if (HAS_SHADING_NORMALS || HAS_TEXTURES) {
        let sh = triangle_shading[hit.prim];
//#if shading_normals
        if (HAS_SHADING_NORMALS && (sh.flags & SHADING_HAS_NORMALS) != 0u) {
            let n = normalize(sh.n0 * w + sh.n1 * hit.u + sh.n2 * hit.v);
            ns = select(n, -n, dot(n, ng) < 0.0);
        }
//#endif
//#if textures
        if (HAS_TEXTURES && (sh.flags & SHADING_HAS_UVS) != 0u) {
            uv = vec2<f32>(sh.u0, sh.v0) * w + vec2<f32>(sh.u1, sh.v1) * hit.u
                + vec2<f32>(sh.u2, sh.v2) * hit.v;
        }
//#endif
    }
//#endif
    return SurfaceHit(position, ng, ns, uv, material, offset, back_offset(magnitude, hit.t));
}

//#if textures|environment_map|constant_environment
// surface.rs `texel_float`: word i of the texel buffer as the f32 whose bits it holds.
fn texel_float(i: u32) -> f32 {
    return bitcast<f32>(texels[i]);
}
//#endif

//#if textures|environment_map
// surface.rs `srgb8`, `texel`: 8-bit sRGB codes (one word a texel) through the table at
// SRGB8_TABLE, or three float words a texel.
fn srgb8(c: u32) -> f32 {
    return texel_float(SRGB8_TABLE + c);
}

fn texel(offset: u32, width: u32, format: u32, x: u32, y: u32) -> vec3<f32> {
    let j = y * width + x;
    if (format == TEXELS_SRGB8) {
        let w = texels[offset + j];
        return vec3<f32>(srgb8(w & 0xffu), srgb8((w >> 8u) & 0xffu), srgb8((w >> 16u) & 0xffu));
    }
    let i = offset + 3u * j;
    return vec3<f32>(texel_float(i), texel_float(i + 1u), texel_float(i + 2u));
}
//#endif

//#if textures|environment_map
// surface.rs `wrap_index`: `((i % n) + n) % n`, with the -1..=n a bilinear lookup asks
// wrapped by one addition or subtraction (the same values).
fn wrap_index(i: i32, n: i32) -> i32 {
    let r = select(select(i, i - n, i >= n), i + n, i < 0);
    if (0 <= r && r < n) {
        return r;
    }
    return ((i % n) + n) % n;
}
//#endif

//#if textures|environment_map
fn texture_bilinear(offset: u32, width: u32, height: u32, format: u32, uv: vec2<f32>, wrap_v: bool) -> vec3<f32> {
    let w = i32(width);
    let h = i32(height);
    let u = uv.x - floor(uv.x);
    var v = min(max(uv.y, 0.0), 1.0);
    if (wrap_v) {
        v = uv.y - floor(uv.y);
    }
    let x = u * f32(width) - 0.5;
    let y = v * f32(height) - 0.5;
    let x0f = floor(x);
    let y0f = floor(y);
    let fx = x - x0f;
    let fy = y - y0f;
    let x0 = i32(x0f);
    let y0 = i32(y0f);
    let ix0 = u32(wrap_index(x0, w));
    let ix1 = u32(wrap_index(x0 + 1, w));
    var iy0 = u32(min(max(y0, 0), h - 1));
    var iy1 = u32(min(max(y0 + 1, 0), h - 1));
    if (wrap_v) {
        iy0 = u32(wrap_index(y0, h));
        iy1 = u32(wrap_index(y0 + 1, h));
    }
    let t00 = texel(offset, width, format, ix0, iy0);
    let t10 = texel(offset, width, format, ix1, iy0);
    let t01 = texel(offset, width, format, ix0, iy1);
    let t11 = texel(offset, width, format, ix1, iy1);
    let top = t00 * (1.0 - fx) + t10 * fx;
    let bottom = t01 * (1.0 - fx) + t11 * fx;
    return top * (1.0 - fy) + bottom * fy;
}
//#endif

fn material_at(surface: SurfaceHit) -> GpuMaterial {
    var m = materials[surface.material];
//#if textures
    if (HAS_TEXTURES && m.texture != NO_TEXTURE && m.kind != MATERIAL_GLASS) {
        let h = texture_headers[m.texture];
        m.color = m.color * texture_bilinear(h.offset, h.width, h.height, h.format, surface.uv, true);
    }
//#endif
    return m;
}

fn environment_radiance(dir: vec3<f32>) -> vec3<f32> {
//#if constant_environment
    if (HAS_CONSTANT_ENVIRONMENT && scene.environment_kind == ENVIRONMENT_CONSTANT) {
        return scene.environment_color;
    }
//#endif
//#if environment_map
    if (HAS_ENVIRONMENT_MAP && scene.environment_kind == ENVIRONMENT_MAP) {
        let e = direction_to_equirect(dir);
        let uv = vec2<f32>(e.x + scene.environment_rotation, e.y);
        let l = texture_bilinear(
            scene.environment_offset,
            scene.environment_width,
            scene.environment_height,
            TEXELS_LINEAR,
            uv,
            false,
        );
        return l * scene.environment_color;
    }
//#endif
    return vec3<f32>(0.0);
}

//#if constant_environment|environment_map
// surface.rs `cdf_search`: the first i < count with cdf[i] > u, the CDF at texels[base..].
fn cdf_search(base: u32, count: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = count - 1u;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (texel_float(base + mid) > u) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}
//#endif

//#if constant_environment|environment_map
// surface.rs `cdf_step`: (cdf[i] - cdf[i - 1], cdf[i - 1]).
fn cdf_step(base: u32, i: u32) -> vec2<f32> {
    var before = 0.0;
    if (i > 0u) {
        before = texel_float(base + i - 1u);
    }
    return vec2<f32>(texel_float(base + i) - before, before);
}
//#endif

// surface.rs `environment_cell`: the guide cell of point p.
fn environment_cell(p: vec3<f32>) -> u32 {
    // Without a spatial guide every point is in cell 0 (the clamps below give 0).
    if (all(scene.environment_grid <= vec3<u32>(1u))) {
        return 0u;
    }
    let q = (p - scene.scene_min) * scene.environment_grid_scale;
    let n = max(scene.environment_grid, vec3<u32>(1u));
    let top = vec3<f32>(n) - vec3<f32>(1.0);
    let c = vec3<u32>(min(max(q, vec3<f32>(0.0)), top));
    return (c.z * n.y + c.y) * n.x + c.x;
}

//#if constant_environment|environment_map
// surface.rs `environment_cdf_base`: the first float of cell `cell`'s distribution.
fn environment_cdf_base(cell: u32) -> u32 {
    let h = scene.environment_cdf_height;
    return scene.environment_cdf + cell * (h + scene.environment_cdf_width * h);
}
//#endif

// surface.rs `environment_pdf`.
fn environment_pdf(dir: vec3<f32>, cell: u32) -> f32 {
    if (!((HAS_CONSTANT_ENVIRONMENT || HAS_ENVIRONMENT_MAP) && scene.environment_cdf_width != 0u)) {
        return 0.25 * INV_PI;
    }
//#if constant_environment|environment_map
    let sin_theta = sqrt(max(1.0 - dir.y * dir.y, 0.0));
    if (!(sin_theta > 0.0)) {
        return 0.0;
    }
    let e = direction_to_equirect(dir);
    let u0 = e.x + scene.environment_rotation;
    let u = u0 - floor(u0);
    let w = scene.environment_cdf_width;
    let h = scene.environment_cdf_height;
    let x = min(u32(u * f32(w)), w - 1u);
    let y = min(u32(min(max(e.y, 0.0), 1.0) * f32(h)), h - 1u);
    let base = environment_cdf_base(cell);
    let p_row = cdf_step(base, y).x;
    let p_col = cdf_step(base + h + y * w, x).x;
    return p_row * p_col * f32(w * h) / (2.0 * PI * PI * sin_theta);
//#else
    return 0.25 * INV_PI;
//#endif
}

// surface.rs `sample_environment`: a direction and its solid-angle pdf.
struct EnvironmentSample {
    dir: vec3<f32>,
    pdf: f32,
}

fn sample_environment(u: vec2<f32>, cell: u32) -> EnvironmentSample {
    if (!((HAS_CONSTANT_ENVIRONMENT || HAS_ENVIRONMENT_MAP) && scene.environment_cdf_width != 0u)) {
        let z = 1.0 - 2.0 * u.x;
        let r = sqrt(max(1.0 - z * z, 0.0));
        let sc = sin_cos_turns(u.y);
        return EnvironmentSample(vec3<f32>(r * sc.y, z, r * sc.x), 0.25 * INV_PI);
    }
//#if constant_environment|environment_map
    let w = scene.environment_cdf_width;
    let h = scene.environment_cdf_height;
    let base = environment_cdf_base(cell);
    let y = cdf_search(base, h, u.x);
    let row = cdf_step(base, y);
    let columns = base + h + y * w;
    let x = cdf_search(columns, w, u.y);
    let col = cdf_step(columns, x);
    let fv = clamp((u.x - row.y) / row.x, 0.0, 1.0);
    let fu = clamp((u.y - col.y) / col.x, 0.0, 1.0);
    let v = (f32(y) + fv) / f32(h);
    let tex_u = (f32(x) + fu) / f32(w);
    // theta = v π (half a turn), phi = (tex_u - rotation - 1/2) turns.
    let theta = sin_cos_turns(0.5 * v);
    let phi = sin_cos_turns(tex_u - scene.environment_rotation - 0.5);
    let sin_theta = theta.x;
    let dir = vec3<f32>(sin_theta * phi.x, theta.y, -sin_theta * phi.y);
    if (!(sin_theta > 0.0 && row.x > 0.0 && col.x > 0.0)) {
        return EnvironmentSample(dir, 0.0);
    }
    return EnvironmentSample(dir, row.x * col.x * f32(w * h) / (2.0 * PI * PI * sin_theta));
//#else
    return EnvironmentSample(vec3<f32>(0.0, 1.0, 0.0), 0.0);
//#endif
}

// The next ray's origin: pushed off the surface by a bound on the rounding error of the hit
// point and of re-finding the primitive from there (surface.rs documents the derivation).
const UNIT_ROUNDOFF: f32 = 1.0 / 16777216.0;
const OFFSET_HIT_ULPS: f32 = 8.0;
const OFFSET_T_ULPS: f32 = 4.0;
const OFFSET_BACK_ULPS: f32 = 16.0;

fn hit_offset(n: vec3<f32>, magnitude: vec3<f32>, extent: f32, aspect: f32) -> f32 {
    return OFFSET_HIT_ULPS * UNIT_ROUNDOFF * dot(abs(n), magnitude)
        + OFFSET_T_ULPS * UNIT_ROUNDOFF * extent * max(aspect, 1.0);
}

fn back_offset(magnitude: vec3<f32>, t: f32) -> f32 {
    return min(OFFSET_BACK_ULPS * UNIT_ROUNDOFF * max(magnitude.x, max(magnitude.y, magnitude.z)), 0.5 * t);
}

// Back along the incoming ray (reflection) or its tangential part (transmission), then off
// the surface along n: see surface.rs.
fn offset_ray_origin(hit: SurfaceHit, dir_in: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let ng = hit.geometric_normal;
    let back = select(dir_in - ng * dot(dir_in, ng), dir_in, dot(dir_in, n) < 0.0);
    return hit.position - back * hit.back_offset + n * hit.offset;
}
