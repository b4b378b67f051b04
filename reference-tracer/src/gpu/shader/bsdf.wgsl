// ---------------------------------------------------------------------------------
// Materials (material/*.rs): f·cos, pdf and sampling in the local frame (z = normal
// facing the viewer; for dielectrics the outside).

fn fresnel_dielectric(cos_incident: f32, eta: f32) -> f32 {
    let sin2_t = max(1.0 - cos_incident * cos_incident, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) { return 1.0; }
    let cos_t = sqrt(1.0 - sin2_t);
    let parallel = (eta * cos_incident - cos_t) / (eta * cos_incident + cos_t);
    let perpendicular = (cos_incident - eta * cos_t) / (cos_incident + eta * cos_t);
    return 0.5 * (parallel * parallel + perpendicular * perpendicular);
}

fn fresnel_conductor(cos_incident: f32, eta: vec3<f32>, k: vec3<f32>) -> vec3<f32> {
    let c = clamp(cos_incident, 0.0, 1.0);
    let cos2 = vec3<f32>(c * c);
    let sin2 = vec3<f32>(1.0) - cos2;
    let eta2 = eta * eta;
    let k2 = k * k;
    let t0 = eta2 - k2 - sin2;
    let a2b2 = sqrt(max(t0 * t0 + 4.0 * eta2 * k2, vec3<f32>(0.0)));
    let t1 = a2b2 + cos2;
    let a = sqrt(max(0.5 * (a2b2 + t0), vec3<f32>(0.0)));
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / max(t1 + t2, vec3<f32>(1e-30));
    let t3 = cos2 * a2b2 + sin2 * sin2;
    let t4 = t2 * sin2;
    let rp = rs * (t3 - t4) / max(t3 + t4, vec3<f32>(1e-30));
    return clamp(0.5 * (rp + rs), vec3<f32>(0.0), vec3<f32>(1.0));
}

fn ggx_d(alpha: f32, h: vec3<f32>) -> f32 {
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

fn ggx_lambda(alpha: f32, w: vec3<f32>) -> f32 {
    let cos2 = w.z * w.z;
    if (cos2 <= 0.0) { return INFINITY; }
    let tan2 = max(1.0 - cos2, 0.0) / cos2;
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}

fn ggx_reflection_pdf(alpha: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (wo.z <= 0.0 || wi.z <= 0.0) { return 0.0; }
    let h = normalize(wo + wi);
    return ggx_d(alpha, h) / ((1.0 + ggx_lambda(alpha, wo)) * 4.0 * wo.z);
}

// Heitz 2018: a visible normal, reflected; returns wi (z <= 0 for a failed draw).
fn ggx_sample(alpha: f32, wo: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let vh = normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let length2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(length2), length2 > 0.0);
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    let h = normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
    return 2.0 * dot(wo, h) * h - wo;
}

fn conductor_fresnel(m: Material, cos_incident: f32) -> vec3<f32> {
    if (m.fresnel == 0u) { return vec3<f32>(1.0); }
    return fresnel_conductor(cos_incident, m.eta.xyz, m.k.xyz);
}

fn is_delta(m: Material) -> bool {
    return m.kind == DIELECTRIC || m.kind == THIN_DIELECTRIC || (m.kind == CONDUCTOR && m.alpha == 0.0);
}

fn bsdf_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> vec3<f32> {
    if (wo.z <= 0.0 || wi.z <= 0.0) { return vec3<f32>(0.0); }
    if (m.kind == DIFFUSE) { return m.albedo.xyz * (wi.z / PI); }
    if (m.kind == CONDUCTOR && m.alpha > 0.0) {
        let alpha = max(m.alpha, 1e-4);
        let h = normalize(wo + wi);
        let g2 = 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
        return m.albedo.xyz * conductor_fresnel(m, dot(wo, h)) * (ggx_d(alpha, h) * g2 / (4.0 * wo.z));
    }
    return vec3<f32>(0.0);
}

fn bsdf_pdf(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (m.kind == DIFFUSE) { return select(0.0, max(wi.z, 0.0) / PI, wo.z > 0.0); }
    if (m.kind == CONDUCTOR && m.alpha > 0.0) { return ggx_reflection_pdf(max(m.alpha, 1e-4), wo, wi); }
    return 0.0;
}

struct BsdfSample {
    wi: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    ok: bool,
};

fn bsdf_sample(m: Material, wo: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> BsdfSample {
    var s: BsdfSample;
    s.ok = false;
    if (m.kind == DIFFUSE) {
        if (wo.z <= 0.0) { return s; }
        s.wi = cosine_hemisphere(u);
        s.pdf = s.wi.z / PI;
        s.weight = m.albedo.xyz;
        s.ok = s.pdf > 0.0;
        return s;
    }
    if (m.kind == CONDUCTOR) {
        if (wo.z <= 0.0) { return s; }
        if (m.alpha == 0.0) {
            s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
            s.weight = m.albedo.xyz * conductor_fresnel(m, wo.z);
            s.pdf = 1.0;
            s.ok = true;
            return s;
        }
        let alpha = max(m.alpha, 1e-4);
        let wi = ggx_sample(alpha, wo, u);
        if (wi.z <= 0.0) { return s; }
        let pdf = ggx_reflection_pdf(alpha, wo, wi);
        if (!(pdf > 0.0 && pdf < INFINITY)) { return s; }
        let h = normalize(wo + wi);
        let ratio = (1.0 + ggx_lambda(alpha, wo)) / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
        s.wi = wi;
        s.pdf = pdf;
        s.weight = m.albedo.xyz * conductor_fresnel(m, dot(wo, h)) * ratio;
        s.ok = true;
        return s;
    }
    if (wo.z == 0.0) { return s; }
    if (m.kind == THIN_DIELECTRIC) {
        let r = fresnel_dielectric(abs(wo.z), m.ior);
        let reflectance = 2.0 * r / (1.0 + r);
        s.weight = vec3<f32>(1.0);
        s.ok = true;
        if (u_lobe < reflectance) {
            s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
            s.pdf = reflectance;
        } else {
            s.wi = -wo;
            s.pdf = 1.0 - reflectance;
        }
        return s;
    }
    // Smooth glass.
    let entering = wo.z > 0.0;
    let eta = select(1.0 / m.ior, m.ior, entering);
    let cos_i = abs(wo.z);
    let reflectance = fresnel_dielectric(cos_i, eta);
    s.ok = true;
    if (u_lobe < reflectance) {
        s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
        s.weight = vec3<f32>(1.0);
        s.pdf = reflectance;
        return s;
    }
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    s.wi = normalize(vec3<f32>(-wo.x / eta, -wo.y / eta, select(cos_t, -cos_t, entering)));
    s.weight = vec3<f32>(1.0 / (eta * eta));
    s.pdf = 1.0 - reflectance;
    return s;
}
