//! The shortest guided path tracer to copy (`cargo run --release --example guided_path_tracer`): a box
//! with a ceiling light, the obvhs intersector, next-event estimation with MIS, and a hemisphere grid that
//! learns from every path through the path recorder and guides the next ones. Renders unguided and guided,
//! writes out/guided_path_tracer.ppm, and fails unless the two image means agree within 4 standard errors.
use std::f32::consts::{FRAC_1_PI, PI};

use glam::{Vec2, Vec3};
use guiding_core::{square_to_triangle_barycentrics, Frame, Guide, HemisphereGrid, HemisphereGridSettings};
use guiding_core::{Intersector, PathRecorder, Pcg32, ProbeId, Ray, Triangle};
use guiding_obvhs::{BvhKind, ObvhsIntersector};

const SIZE: u32 = 48;
const PASSES: u32 = 48;
const ALBEDO: f32 = 0.7;
const EMISSION: f32 = 15.0;
const GUIDE_SHARE: f32 = 0.5;

/// The unit box seen from z = -1, a panel, and last the light's two triangles (corners counter-clockwise).
fn scene() -> Vec<Triangle> {
    let quads: [[[f32; 3]; 4]; 7] = [
        [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]], // floor
        [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]], // ceiling
        [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]], // back
        [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]], // left
        [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]], // right
        [[0.6, 0., 0.3], [0.6, 0.4, 0.3], [0.9, 0.4, 0.6], [0.9, 0., 0.6]], // panel
        [[0.4, 0.99, 0.4], [0.6, 0.99, 0.4], [0.6, 0.99, 0.6], [0.4, 0.99, 0.6]], // light
    ];
    let quad = |[a, b, c, d]: [[f32; 3]; 4]| {
        [[a, b, c], [a, c, d]].map(|[a, b, c]| Triangle::new(a.into(), b.into(), c.into()))
    };
    quads.into_iter().flat_map(quad).collect()
}

struct Tracer {
    triangles: Vec<Triangle>,
    light: usize, // the first light triangle
    light_area: f32,
    bvh: ObvhsIntersector,
    guide: Option<HemisphereGrid>,
}

/// One path's radiance; with a guide it samples it and teaches it (through `path`).
fn radiance(tracer: &Tracer, mut ray: Ray, path: &mut PathRecorder<ProbeId>, rng: &mut Pcg32) -> f32 {
    let (mut throughput, mut radiance, mut last_pdf) = (1.0f32, 0.0f32, None::<f32>);
    let mis = |a: f32, b: f32| a * a / (a * a + b * b); // the power heuristic
    let light_pdf =
        |a: Vec3, p: Vec3, n: Vec3| a.distance_squared(p) / (tracer.light_area * n.dot((a - p).normalize()));
    path.clear();
    for depth in 0..16 {
        let Some(hit) = tracer.bvh.intersect(&ray) else { break };
        path.reached(hit.t);
        let point = ray.origin + ray.direction * hit.t;
        let mut normal = tracer.triangles[hit.primitive as usize].normal().expect("no degenerate triangles");
        if hit.primitive as usize >= tracer.light {
            if normal.dot(ray.direction) < 0.0 {
                let weight = last_pdf.map_or(1.0, |pdf| mis(pdf, light_pdf(ray.origin, point, normal)));
                radiance += throughput * EMISSION * weight;
                path.arrive(EMISSION * weight);
            }
            break;
        }
        normal = if normal.dot(ray.direction) > 0.0 { -normal } else { normal };
        let located = tracer.guide.as_ref().and_then(|g| Some((g, g.locate(point, normal)?)));
        let cosine_pdf = |wi: Vec3| wi.dot(normal).max(0.0) * FRAC_1_PI;
        let scatter_pdf = |wi: Vec3| match located {
            Some((g, r)) => GUIDE_SHARE * g.pdf(r, wi) + (1.0 - GUIDE_SHARE) * cosine_pdf(wi),
            None => cosine_pdf(wi),
        };
        let light = &tracer.triangles[tracer.light + usize::from(rng.next_f32() < 0.5)]; // next-event estimation
        let on_light = light.point(square_to_triangle_barycentrics(rng.next_vec2()));
        let (wi, distance, spawn) = ((on_light - point).normalize(), on_light.distance(point), point + normal * 1e-4);
        let light_normal = light.normal().expect("a light with area");
        let shadow = Ray::segment(spawn, wi, 0.0, distance * 0.999);
        if wi.dot(normal) > 0.0 && wi.dot(light_normal) < 0.0 && !tracer.bvh.occluded(&shadow) {
            let light_pdf = light_pdf(point, on_light, light_normal);
            let direct = ALBEDO * cosine_pdf(wi) * EMISSION / light_pdf * mis(light_pdf, scatter_pdf(wi));
            radiance += throughput * direct;
            path.arrive(direct); // indirect light for the previous vertex
        }
        // Scatter: the guide with probability GUIDE_SHARE where it has a region, else the cosine.
        let (u_choice, u) = (rng.next_f32(), rng.next_vec2());
        let wi = match located {
            Some((g, r)) if u_choice < GUIDE_SHARE => g.sample(r, u).direction,
            _ => {
                let (r, phi) = (u.x.sqrt(), 2.0 * PI * u.y); // cosine-distributed
                Frame::from_normal(normal).to_world(Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).sqrt()))
            }
        };
        let pdf = scatter_pdf(wi);
        if wi.dot(normal) <= 0.0 || pdf <= 0.0 {
            break;
        }
        let mut factor = ALBEDO * cosine_pdf(wi) / pdf;
        throughput *= factor;
        let survival = if depth >= 3 { throughput.min(0.95) } else { 1.0 }; // Russian roulette
        if survival < 1.0 && rng.next_f32() >= survival {
            break;
        }
        (throughput, factor) = (throughput / survival, factor / survival);
        path.carry(factor); // this vertex learns from the path's own continuation, passed back by the factor
        path.scattered(located.map(|(_, r)| r), point, wi, pdf, throughput, ());
        (ray, last_pdf) = (Ray::new(spawn, wi), Some(pdf));
    }
    tracer.guide.as_ref().map(|guide| path.learn(guide, true)); // each target of Eq. (1), weighed by its pdf
    radiance
}

/// PASSES passes of one path per pixel: the image, and the mean and standard error of the passes' means.
fn render(tracer: &mut Tracer, seed: u64) -> (Vec<f32>, f64, f64) {
    let (mut image, mut means, mut path) = (vec![0.0f32; (SIZE * SIZE) as usize], Vec::new(), PathRecorder::new());
    for pass in 0..PASSES {
        let mut sum = 0.0f64;
        for pixel in 0..SIZE * SIZE {
            let mut rng = Pcg32::new(seed ^ (u64::from(pass) << 32), u64::from(pixel));
            let (x, y) = ((pixel % SIZE) as f32, (pixel / SIZE) as f32);
            let screen = (Vec2::new(x, y) + rng.next_vec2()) / SIZE as f32 - 0.5;
            let ray = Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::new(0.8 * screen.x, -0.8 * screen.y, 1.0).normalize());
            let value = radiance(tracer, ray, &mut path, &mut rng);
            image[pixel as usize] += value / PASSES as f32;
            sum += f64::from(value) / f64::from(SIZE * SIZE);
        }
        means.push(sum);
        tracer.guide.as_mut().map(Guide::rebuild_sampling); // between passes
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    let variance = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (means.len() - 1) as f64;
    (image, mean, (variance / means.len() as f64).sqrt())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let triangles = scene();
    let (light, bvh) = (triangles.len() - 2, ObvhsIntersector::build(&triangles, BvhKind::default()));
    let light_area = triangles[light..].iter().map(Triangle::area).sum();
    let guide = HemisphereGrid::build(&triangles[..light], HemisphereGridSettings::default())?;
    let mut tracer = Tracer { triangles, light, light_area, bvh, guide: None };
    let (_, a, sa) = render(&mut tracer, 1);
    tracer.guide = Some(guide);
    let (image, b, sb) = render(&mut tracer, 2);
    println!("unguided mean {a:.5} ± {sa:.5}, guided mean {b:.5} ± {sb:.5}");
    std::fs::create_dir_all("out")?;
    let pixels = image.iter().flat_map(|&v| [(255.0 * (v / (1.0 + v)).sqrt()) as u8; 3]);
    let header = format!("P6 {SIZE} {SIZE} 255\n").into_bytes();
    std::fs::write("out/guided_path_tracer.ppm", [header, pixels.collect()].concat())?;
    if (a - b).abs() > 4.0 * (sa * sa + sb * sb).sqrt() {
        return Err(format!("the means disagree: {a} against {b}").into());
    }
    println!("means agree; wrote out/guided_path_tracer.ppm");
    Ok(())
}
