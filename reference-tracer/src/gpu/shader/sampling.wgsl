// ---------------------------------------------------------------------------------
// Frames and sampling.

struct Frame {
    tangent: vec3<f32>,
    bitangent: vec3<f32>,
    normal: vec3<f32>,
};

// guiding-core's Frame::from_normal (Duff et al.).
fn frame_from_normal(n: vec3<f32>) -> Frame {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    var f: Frame;
    f.tangent = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.bitangent = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    f.normal = n;
    return f;
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.tangent), dot(v, f.bitangent), dot(v, f.normal));
}

fn to_world(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return f.tangent * v.x + f.bitangent * v.y + f.normal * v.z;
}

// The unit vector with z = `z` and azimuth `phi` about the z axis.
fn spherical_direction(z: f32, phi: f32) -> vec3<f32> {
    let r = sqrt(max(1.0 - z * z, 0.0));
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let a = pdf * pdf;
    let b = other * other;
    if (a + b > 0.0 && a < INFINITY) { return a / (a + b); }
    return select(0.0, 1.0, a >= INFINITY);
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}
