// ---------------------------------------------------------------------------------
// The Gaussian mixture (guiding-core's mixture/): a grid cell and normal side per
// region, a vMF mixture over the sphere sampled and evaluated exactly, learned by
// adding each sample's responsibilities into the region's batch sums; the M-step runs
// on the host between passes.

const LOBE_WORDS: u32 = 8u;

// expm1 and log1p without cancellation near 0 (WGSL has neither).
fn expm1(x: f32) -> f32 {
    if (abs(x) < 1e-2) { return x * (1.0 + x * (0.5 + x * (0.16666667 + x * 0.041666668))); }
    return exp(x) - 1.0;
}

fn log1p(x: f32) -> f32 {
    if (abs(x) < 1e-2) { return x * (1.0 - x * (0.5 - x * (0.33333334 - x * 0.25))); }
    return log(1.0 + x);
}

// GaussianMixture::locate: the grid cell, then the normal's dominant axis and sign.
fn mixture_locate(p: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (!all(abs(p) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    let cell = grid_cell(p).index;
    var side = 0u;
    if (params.regions_per_cell == 6u) {
        let a = abs(normal);
        var axis = 2u;
        if (a.x >= a.y && a.x >= a.z) { axis = 0u; } else if (a.y >= a.z) { axis = 1u; }
        side = 2u * axis + select(0u, 1u, normal[axis] < 0.0);
    }
    return cell * params.regions_per_cell + side;
}

fn lobe_word(region: u32, k: u32, i: u32) -> f32 {
    return cdf[(region * params.guide_patches + k) * LOBE_WORDS + i];
}

fn lobe_mean(region: u32, k: u32) -> vec3<f32> {
    return vec3<f32>(lobe_word(region, k, 0u), lobe_word(region, k, 1u), lobe_word(region, k, 2u));
}

// VmfLobe::pdf: C(κ)·e^{κ(μ·d − 1)}, with μ·d − 1 = −|d − μ|²/2.
fn lobe_pdf(region: u32, k: u32, d: vec3<f32>) -> f32 {
    let kappa = lobe_word(region, k, 3u);
    if (kappa == 0.0) { return lobe_word(region, k, 4u); }
    let m = d - lobe_mean(region, k);
    return lobe_word(region, k, 4u) * exp(kappa * (-0.5 * dot(m, m)));
}

// MixtureDistribution::sphere_pdf: the mixture with uniform_mix spread over the sphere.
fn mixture_sphere_pdf(region: u32, d: vec3<f32>) -> f32 {
    var sum = 0.0;
    for (var k = 0u; k < params.guide_patches; k += 1u) { sum += lobe_word(region, k, 5u) * lobe_pdf(region, k, d); }
    return (1.0 - params.uniform_mix) * sum + params.uniform_mix * (0.25 / PI);
}

// MixtureDistribution::pdf: folded onto the normal's hemisphere, as the volume's.
fn mixture_pdf(region: u32, normal: vec3<f32>, d: vec3<f32>) -> f32 {
    if (!(dot(d, normal) >= 0.0)) { return 0.0; }
    return mixture_sphere_pdf(region, d) + mixture_sphere_pdf(region, mirror(d, normal));
}

// VmfLobe::sample (Jakob's w = 1 + ln(u + (1 − u)e^{−2κ})/κ).
fn lobe_sample(region: u32, k: u32, u: vec2<f32>) -> vec3<f32> {
    let kappa = lobe_word(region, k, 3u);
    var w = 1.0 - 2.0 * u.x;
    if (kappa != 0.0) { w = clamp(1.0 + log1p((1.0 - u.x) * expm1(-2.0 * kappa)) / kappa, -1.0, 1.0); }
    let local = spherical_direction(w, 2.0 * PI * u.y);
    return normalize(to_world(frame_from_normal(lobe_mean(region, k)), local));
}

fn mixture_sample(region: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    let mix = params.uniform_mix;
    var d = vec3<f32>(0.0);
    if (u.x < mix) {
        d = spherical_direction(1.0 - 2.0 * (u.x / mix), 2.0 * PI * u.y);
    } else {
        let x = min((u.x - mix) / (1.0 - mix), 0.99999994);
        let lobes = params.guide_patches;
        var chosen = lobes - 1u;
        var low = 0.0;
        var cumulative = 0.0;
        for (var k = 0u; k < lobes; k += 1u) {
            let next = cumulative + lobe_word(region, k, 5u);
            if (x < next || k == lobes - 1u) {
                chosen = k;
                low = cumulative;
                break;
            }
            cumulative = next;
        }
        let width = lobe_word(region, chosen, 5u);
        var rest = 0.5;
        if (width > 0.0) { rest = clamp((x - low) / width, 0.0, 0.99999994); }
        d = lobe_sample(region, chosen, vec2<f32>(rest, u.y));
    }
    d = fold_onto_hemisphere(d, normal);
    var s: GuideSample;
    s.wi = d;
    s.pdf = mixture_pdf(region, normal, d);
    return s;
}

// A float added to batch word `index` by compare-exchange, saturating at ±f32::MAX.
fn add_to_batch(index: u32, value: f32) {
    if (value == 0.0) { return; }
    var old = atomicLoad(&q[index]);
    loop {
        let sum = clamp(bitcast<f32>(old) + value, -3.4028235e38, 3.4028235e38);
        let result = atomicCompareExchangeWeak(&q[index], old, bitcast<u32>(sum));
        if (result.exchanged) { break; }
        old = result.old_value;
    }
}

// The learning hooks of the guide dispatch (guide.wgsl): a region is a cell's normal
// side; mixture_locate, _pdf and _sample are above.

// GaussianMixture::update_sampled: v = target / sampling pdf, split over the lobes by
// their responsibilities into the region's batch sums.
fn mixture_learn(region: u32, normal: vec3<f32>, d: vec3<f32>, goal: f32, pdf: f32) {
    if (!(abs(dot(d, d) - 1.0) < 1e-3 && pdf > 0.0 && pdf < INFINITY)) { return; }
    let weight = min(goal / pdf, 1e30);
    let lobes = params.guide_patches;
    let stride = 1u + 4u * lobes;
    let base = region * stride;
    var total = 0.0;
    for (var k = 0u; k < lobes; k += 1u) { total += lobe_word(region, k, 5u) * lobe_pdf(region, k, d); }
    let fallback = u32(lobe_word(region, 0u, 7u));
    // The count saturates, as guiding-core's increment does.
    var count = atomicLoad(&q[base]);
    loop {
        if (count == 0xffffffffu) { break; }
        let result = atomicCompareExchangeWeak(&q[base], count, count + 1u);
        if (result.exchanged) { break; }
        count = result.old_value;
    }
    for (var k = 0u; k < lobes; k += 1u) {
        var r = select(0.0, 1.0, k == fallback);
        if (total > 0.0 && total < INFINITY) { r = lobe_word(region, k, 5u) * lobe_pdf(region, k, d) / total; }
        let share = r * weight;
        let word = base + 1u + 4u * k;
        add_to_batch(word, share);
        add_to_batch(word + 1u, share * d.x);
        add_to_batch(word + 2u, share * d.y);
        add_to_batch(word + 3u, share * d.z);
    }
}

// GaussianMixture::estimate_integral: S·Σ_k w_k·fs(ω_k)·cos θ_k with ω_k drawn from
// lobe k by the same `u`.
fn mixture_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    let scale = lobe_word(region, 0u, 6u);
    if (!(scale > 0.0)) { return 0.0; }
    var sum = 0.0;
    for (var k = 0u; k < params.guide_patches; k += 1u) {
        let wi = lobe_sample(region, k, u);
        sum += lobe_word(region, k, 5u) * luminance(bsdf_eval(m, wo_local, to_local(shading.frame, wi)));
    }
    return min(scale * sum, 3.4e38);
}

// The host takes the M-step between passes: the rebuild kernel has nothing to do.
fn mixture_rebuild(region: u32) {}
