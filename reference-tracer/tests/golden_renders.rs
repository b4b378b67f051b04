//! Unguided renders against images recorded before a change: a refactor of the
//! integrator (issue 23's move, or a faster path loop that keeps the scalar one as its
//! reference) must leave every sample as it was. `pt`, `nee` and `light` on cornell and
//! door at 20×16, 6 samples per pixel, seed 17, obvhs; the recorded images are
//! `tests/golden/SCENE-METHOD.pfm`.
//!
//! The images agree bit for bit on the machine that recorded them. Elsewhere the C
//! library's sine and cosine may round their last bit otherwise, which moves a pixel by
//! about 1e-7 of its value: a pixel may differ by 1e-5 of its value (or of 1) and no
//! more, while a changed sampling decision moves pixels at this sample count by tens of
//! percent. After a change that is meant to alter unguided renders, record them again
//! with `LODESTAR_RECORD_GOLDEN=1 cargo test --test golden_renders` and say so in the
//! commit.

mod support;

use std::path::PathBuf;

use reference_tracer::integrator::Method;
use reference_tracer::output::{read_image, write_pfm, Image};
use support::{render_image, repository_scene, settings};

/// The most a pixel's channel may differ from the recorded one, relative to it (or to 1).
const TOLERANCE: f32 = 1e-5;

fn golden_path(scene: &str, method: Method) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("tests/golden/{scene}-{}.pfm", method.name()))
}

/// Channels that differ from `recorded` by more than the tolerance, and those that
/// differ at all.
fn differences(image: &Image, recorded: &Image) -> (usize, usize) {
    let channels = image.pixels.iter().zip(&recorded.pixels).flat_map(|(a, b)| (0..3).map(move |c| (a[c], b[c])));
    channels.fold((0, 0), |(far, any), (a, b)| {
        // A NaN on either side is beyond.
        let within = (a - b).abs() <= TOLERANCE * (1.0 + b.abs());
        let beyond = !within;
        (far + beyond as usize, any + (a.to_bits() != b.to_bits()) as usize)
    })
}

#[test]
fn unguided_renders_match_the_recorded_images() {
    let record = std::env::var_os("LODESTAR_RECORD_GOLDEN").is_some();
    for scene in ["cornell", "door"] {
        let path = repository_scene(scene, 20, 16);
        for method in [Method::Pt, Method::Nee, Method::Light] {
            let (image, _) = render_image(&path, settings(method), None, 6, 17);
            let golden = golden_path(scene, method);
            if record {
                write_pfm(&golden, &image).unwrap();
                continue;
            }
            let recorded = read_image(&golden).unwrap_or_else(|e| panic!("{}: {e}", golden.display()));
            assert_eq!((image.width, image.height), (recorded.width, recorded.height), "{}", golden.display());
            assert!(recorded.pixels.iter().any(|p| p.max_element() > 0.0), "{}: a black image", golden.display());
            let (far, any) = differences(&image, &recorded);
            assert_eq!(
                far,
                0,
                "{scene} {}: {far} channels differ from {} by more than {TOLERANCE} of their value ({any} differ at all)",
                method.name(),
                golden.display()
            );
            if any > 0 {
                eprintln!("{scene} {}: {any} channels differ in their last bits only", method.name());
            }
        }
    }
}
