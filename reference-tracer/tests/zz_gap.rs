use guiding_core::glam::{Vec2, Vec3};
use guiding_core::{DirectionalDistribution, Guide, Pcg32, SpatialDirectionalTree};

#[test]
#[ignore]
fn gap_mass() {
    let bytes = std::fs::read(std::env::var("GUIDE").unwrap()).unwrap();
    let tree = match SpatialDirectionalTree::from_bytes(&bytes) {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    };
    let mut rng = Pcg32::new(1, 1);
    // (point, normal) probes in the front room.
    let probes = [
        (Vec3::new(0.0, 0.0, 2.0), Vec3::Y),
        (Vec3::new(-1.0, 0.0, 1.0), Vec3::Y),
        (Vec3::new(1.0, 0.0, 3.0), Vec3::Y),
        (Vec3::new(-2.0, 1.0, 2.0), Vec3::X),
        (Vec3::new(2.0, 1.2, 2.0), -Vec3::X),
        (Vec3::new(0.0, 2.5, 2.0), -Vec3::Y),
        (Vec3::new(-1.0, 1.0, 4.5), -Vec3::Z),
        (Vec3::new(-1.0, 1.0, 0.0), Vec3::Z),
    ];
    for (p, n) in probes {
        let region = tree.locate(p, n).unwrap();
        let d = tree.distribution(region);
        let (mut doorway, mut slice, mut cos_doorway, mut cos_slice, mut maxpdf) = (0, 0, 0, 0, 0f32);
        let frame = guiding_core::Frame::from_normal(n);
        let count = 200_000;
        let hits = |w: Vec3| -> (bool, bool) {
            if w.z >= -1e-6 {
                return (false, false);
            }
            let t = -p.z / w.z;
            let q = p + w * t;
            let inside = (0.4..1.2).contains(&q.x) && (0.0..2.1).contains(&q.y);
            (inside, inside && q.x > 1.1)
        };
        for _ in 0..count {
            let s = d.sample(rng.next_vec2());
            maxpdf = maxpdf.max(s.pdf);
            let (a, b) = hits(s.direction);
            doorway += a as u32;
            slice += b as u32;
            let u: Vec2 = rng.next_vec2();
            let r = u.x.sqrt();
            let phi = 2.0 * std::f32::consts::PI * u.y;
            let w = frame.to_world(Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt()));
            let (a, b) = hits(w);
            cos_doorway += a as u32;
            cos_slice += b as u32;
        }
        let f = |x: u32| x as f64 / count as f64;
        eprintln!("{p:?} leaf {} flux {:.3} depth {}: guide doorway {:.4} slice {:.4} | cosine doorway {:.4} slice {:.4} | max pdf {maxpdf:.1}",
            region.leaf, tree.leaf_flux(region.leaf), tree.directional_depth(region.leaf), f(doorway), f(slice), f(cos_doorway), f(cos_slice));
    }
}
