// ---------------------------------------------------------------------------------
// The irradiance volume (guiding-core's volume/): leaf lookup down the octree, the
// whole sphere in equal-area patches in world axes, sampling folded onto the normal's
// hemisphere, and the Lambertian integral from each leaf's spherical harmonics.

const LEAF_BIT: u32 = 0x80000000u;
const MAX_TREE_DEPTH: u32 = 32u;

// IrradianceVolume::leaf_at: the grid cell holding `p` (the nearest one outside), then
// down by octants; NO_PROBE for a non-finite point. Position alone finds the leaf.
fn volume_locate(p: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (!all(abs(p) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    let g = grid_cell(p);
    var offset = clamp(g.scaled - vec3<f32>(g.cell), vec3<f32>(0.0), vec3<f32>(1.0));
    var entry = index_table[g.index];
    for (var depth = 0u; depth < MAX_TREE_DEPTH && (entry & LEAF_BIT) == 0u; depth += 1u) {
        let upper = offset >= vec3<f32>(0.5);
        let octant = select(0u, 1u, upper.x) | select(0u, 2u, upper.y) | select(0u, 4u, upper.z);
        offset = offset * 2.0 - select(vec3<f32>(0.0), vec3<f32>(1.0), upper);
        entry = index_table[entry + octant];
    }
    if ((entry & LEAF_BIT) == 0u) { return NO_PROBE; }
    return entry & ~LEAF_BIT;
}

// SphereLayout::patch_of: bands of z, sectors of φ about the world z axis.
fn sphere_patch_of(direction: vec3<f32>) -> u32 {
    let d = normalize(direction);
    let bands = params.patch_rows;
    let sectors = params.patch_columns;
    let band = min(u32((d.z + 1.0) * 0.5 * f32(bands)), bands - 1u);
    var phi = atan2(d.y, d.x);
    if (phi < 0.0) { phi += 2.0 * PI; }
    let sector = min(u32(phi * (0.5 / PI) * f32(sectors)), sectors - 1u);
    return band * sectors + sector;
}

// SphereLayout::direction_in_patch: uniform in solid angle inside the patch.
fn sphere_direction_in_patch(entry: u32, u: vec2<f32>) -> vec3<f32> {
    let bands = params.patch_rows;
    let sectors = params.patch_columns;
    let z = clamp(-1.0 + 2.0 * (f32(entry / sectors) + u.x) / f32(bands), -1.0, 1.0);
    return spherical_direction(z, 2.0 * PI * (f32(entry % sectors) + u.y) / f32(sectors));
}

fn mirror(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return normalize(d - 2.0 * dot(d, n) * n);
}

// guiding-core's fold_onto_hemisphere: below the surface mirrored, cos θ ≥ MIN_SAMPLED_COS.
fn fold_onto_hemisphere(direction: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    var d = direction;
    if (dot(d, normal) < 0.0) { d = mirror(d, normal); }
    let cos_theta = dot(d, normal);
    if (cos_theta < MIN_SAMPLED_COS) { d = normalize(d + (MIN_SAMPLED_COS - cos_theta) * normal); }
    return d;
}

fn sphere_pdf(leaf: u32, d: vec3<f32>) -> f32 {
    return patch_probability(leaf, sphere_patch_of(d)) * f32(params.guide_patches) / (4.0 * PI);
}

// VolumeDistribution::pdf: p(ω) + p(mirror ω) above the surface, 0 below.
fn volume_pdf(leaf: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (!(dot(wi, normal) >= 0.0)) { return 0.0; }
    return sphere_pdf(leaf, wi) + sphere_pdf(leaf, mirror(wi, normal));
}

fn volume_sample(leaf: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    let c = invert_cdf(leaf, u.x);
    let d = fold_onto_hemisphere(sphere_direction_in_patch(c.entry, vec2<f32>(c.rest, u.y)), normal);
    var s: GuideSample;
    s.wi = d;
    s.pdf = volume_pdf(leaf, normal, d);
    return s;
}

// The nine real spherical harmonics of order ≤ 2 at unit `d` (irradiance_sh.rs; its
// SH_NORMALIZATION are the generated SH_K0…SH_K4).
fn sh_basis(d: vec3<f32>) -> array<f32, 9> {
    return array<f32, 9>(
        SH_K0,
        SH_K1 * d.y,
        SH_K1 * d.z,
        SH_K1 * d.x,
        SH_K2 * d.x * d.y,
        SH_K2 * d.y * d.z,
        SH_K3 * (3.0 * d.z * d.z - 1.0),
        SH_K2 * d.x * d.z,
        SH_K4 * (d.x * d.x - d.y * d.y),
    );
}

// ∫ Q·max(0, n·ω)/π dω from leaf `leaf`'s coefficients (Ramamoorthi–Hanrahan's band
// weights Â_l/π), clamped at 0.
fn sh_cosine_integral(leaf: u32, normal: vec3<f32>) -> f32 {
    let weights = array<f32, 9>(1.0, 0.6666667, 0.6666667, 0.6666667, 0.25, 0.25, 0.25, 0.25, 0.25);
    let y = sh_basis(normal);
    var sum = 0.0;
    for (var i = 0u; i < 9u; i += 1u) {
        sum += weights[i] * bitcast<f32>(atomicLoad(&integral_terms[9u * leaf + i])) * y[i];
    }
    return max(sum, 0.0);
}

// The learning hooks of the guide dispatch (guide.wgsl): a region is a leaf;
// volume_locate, _pdf and _sample are above.

fn volume_learn(region: u32, normal: vec3<f32>, wi: vec3<f32>, goal: f32, pdf: f32) {
    _ = table_learn(region, sphere_patch_of(wi), goal);
}

// ∫ Q fs cos: from the leaf's spherical harmonics for diffuse surfaces, one BSDF sample
// for glossy ones.
fn volume_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    if (m.kind == DIFFUSE) {
        return luminance(m.albedo.xyz) * sh_cosine_integral(region, shading.frame.normal);
    }
    let d = bsdf_direction(m, shading, wo_local, u, u_lobe);
    if (!d.ok) { return 0.0; }
    return table_value(region, sphere_patch_of(d.wi)) * d.weight;
}

// The leaf's projection on the spherical harmonics, then its CDF.
fn volume_rebuild(region: u32) {
    let n = params.guide_patches;
    let base = region * n;
    var sh = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < n; k += 1u) {
        let value = bitcast<f32>(atomicLoad(&q[base + k]));
        for (var i = 0u; i < 9u; i += 1u) { sh[i] += value * patch_weights[9u * k + i]; }
    }
    for (var i = 0u; i < 9u; i += 1u) {
        atomicStore(&integral_terms[9u * region + i], bitcast<u32>(clamp(sh[i], -3.4e38, 3.4e38)));
    }
    table_rebuild_cdf(region);
}
