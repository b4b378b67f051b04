// ---------------------------------------------------------------------------------
// Lights.

// guiding-core's sample_cdf: the index k with cdf[k-1] <= u < cdf[k].
fn sample_light_cdf(u: f32) -> u32 {
    var low = 0u;
    var high = params.light_count;
    while (low < high) {
        let middle = (low + high) / 2u;
        if (light_cdf[middle] <= u) { low = middle + 1u; } else { high = middle; }
    }
    return min(low, params.light_count - 1u);
}

// Density per steradian with which NEE produces the direction from `from` to `point`
// on light `light` (normal `normal`), selection included.
fn light_pdf(light: u32, origin: vec3<f32>, point: vec3<f32>, normal: vec3<f32>) -> f32 {
    let to_light = point - origin;
    let distance2 = dot(to_light, to_light);
    let cos_light = -dot(normal, to_light) / sqrt(distance2);
    if (cos_light <= 0.0) { return 0.0; }
    let l = lights[light];
    return (1.0 - params.environment_choice) * l.emission.w * distance2 / (cos_light * l.v2.w);
}

fn epsilon_at(point: vec3<f32>) -> f32 {
    let a = abs(point);
    return params.ray_epsilon + 1e-6 * max(max(a.x, a.y), a.z);
}

fn spawn(point: vec3<f32>, normal: vec3<f32>, direction: vec3<f32>) -> vec3<f32> {
    let side = select(-1.0, 1.0, dot(normal, direction) >= 0.0);
    return point + normal * (side * epsilon_at(point));
}

struct Shading {
    frame: Frame,
    geometric: vec3<f32>,
};

fn shading_frame(m: Material, geometric_normal: vec3<f32>, wo: vec3<f32>) -> Shading {
    var s: Shading;
    if (m.kind == DIELECTRIC || m.kind == THIN_DIELECTRIC) {
        s.frame = frame_from_normal(geometric_normal);
        s.geometric = geometric_normal;
        return s;
    }
    let n = select(geometric_normal, -geometric_normal, dot(geometric_normal, wo) < 0.0);
    s.frame = frame_from_normal(n);
    s.geometric = n;
    return s;
}

