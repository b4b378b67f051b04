//! Renders that do not learn are reproducible to the last bit, whatever the thread count:
//! every pixel (or light path) draws from its own generator, and the passes are summed
//! in a fixed order. This is what lets a refactor of the integrator be checked by
//! comparing images bit for bit before and after (issue 23's move did so by hashing
//! renders of cornell and Veach Ajar).

mod support;

use reference_tracer::integrator::{IntegratorSettings, Method};
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

/// nee's lane loop renders the image of one path at a time, to the last bit: every path
/// draws its own pixel's numbers in the same order and adds its light in the same order,
/// whatever the lanes beside it. Diffuse scenes, mirrors, glass and rough metal
/// (glossy), and an environment map with a sun (window); 16 lanes, and 5 (which divide
/// no row).
#[test]
fn nee_in_lanes_renders_the_image_of_one_path_at_a_time() {
    for scene in ["cornell", "door", "glossy", "window"] {
        let path = repository_scene(scene, 24, 16);
        let render = |lanes| render_image(&path, IntegratorSettings { lanes, ..settings(Method::Nee) }, None, 4, 23).0;
        let one = render(1);
        assert!(one.pixels.iter().any(|p| p.max_element() > 0.0), "{scene}: a black image");
        for lanes in [5, 16] {
            assert_eq!(bits(&one), bits(&render(lanes)), "{scene}: {lanes} lanes changed the image");
        }
    }
}
