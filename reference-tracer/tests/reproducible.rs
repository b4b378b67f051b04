//! Renders that do not learn are reproducible to the last bit, whatever the thread count:
//! every pixel (or light path) draws from its own generator, and the passes are summed
//! in a fixed order. This is what lets a refactor of the integrator be checked by
//! comparing images bit for bit before and after (issue 23's move did so by hashing
//! renders of cornell and Veach Ajar).

mod support;

use reference_tracer::integrator::Method;
use reference_tracer::output::Image;
use support::{render_image, repository_scene, settings};

fn bits(image: &Image) -> Vec<u32> {
    image.pixels.iter().flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]).collect()
}

#[test]
fn unguided_renders_are_bit_identical_on_one_and_on_three_threads() {
    for scene in ["cornell", "door"] {
        let path = repository_scene(scene, 20, 16);
        for method in [Method::Pt, Method::Nee, Method::Light] {
            let render = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| render_image(&path, settings(method), None, 6, 17).0)
            };
            let (one, three) = (render(1), render(3));
            assert!(one.pixels.iter().any(|p| p.max_element() > 0.0), "{scene} {}: a black image", method.name());
            assert_eq!(bits(&one), bits(&three), "{scene} {}: the thread count changed the image", method.name());
        }
    }
}
