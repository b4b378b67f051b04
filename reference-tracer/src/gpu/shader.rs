//! The GPU tracer's WGSL source: the files of `shader/`, one per concern as the Rust
//! modules are split (header: bindings and structs; rng; intersect; sampling; bsdf;
//! lights; guide_table: what the guide structures share; one file per structure, listed
//! with the rest of its GPU side in `guide_buffers.rs`; guide: the guide's update and
//! kernels; trace: the path, learning and the entry points), concatenated in order. Before
//! them come the constants that carry Rust's codes (methods, material kinds, guide
//! structures, learning rates), guiding-core's spherical-harmonic normalisation and the
//! uniform block `Params`, and after them the dispatch between the guide structures, all
//! generated here from the Rust values and types themselves so the two sides cannot
//! drift, and a structure is added by its own file and its row in `GUIDE_SHADERS`.

use std::fmt::Write;

use super::guide_buffers::GUIDE_SHADERS;
use super::params::{
    method_code, Params, LEARNING_RATE_ENTRY_VISITS, LEARNING_RATE_EXPONENTIAL, LEARNING_RATE_REGION_VISITS,
};
use super::scene_buffers::{MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE, MATERIAL_THIN_DIELECTRIC};
use super::tree_upload::{TREE_FLAG_COSINE, TREE_FLAG_FOLD, TREE_FLAG_PER_AXIS};
use crate::integrator::Method;
use guiding_core::volume::SH_NORMALIZATION;
use guiding_core::FlatTree;

/// The shader's files before the guides', in the order they are joined.
const BEFORE_GUIDES: [&str; 6] = [
    include_str!("shader/header.wgsl"),
    include_str!("shader/rng.wgsl"),
    include_str!("shader/intersect.wgsl"),
    include_str!("shader/sampling.wgsl"),
    include_str!("shader/bsdf.wgsl"),
    include_str!("shader/lights.wgsl"),
];

/// What the guide structures share, before each one's own file ([`GUIDE_SHADERS`]).
const GUIDE_TABLE: &str = include_str!("shader/guide_table.wgsl");

/// The files after the guides': the guide's update and kernels, then the path,
/// learning and the entry points.
const AFTER_GUIDES: [&str; 2] = [include_str!("shader/guide.wgsl"), include_str!("shader/trace.wgsl")];

/// Every shader file, in the order they are joined.
fn parts() -> impl Iterator<Item = &'static str> {
    let guides = GUIDE_SHADERS.iter().map(|guide| guide.source);
    BEFORE_GUIDES.into_iter().chain([GUIDE_TABLE]).chain(guides).chain(AFTER_GUIDES)
}

/// The hooks each structure's shader file defines as `PREFIX_NAME`, and the dispatch
/// `guide_NAME` calls by `params.guide_kind`: name, parameters, return type ("" for
/// none).
const GUIDE_HOOKS: [(&str, &str, &str); 6] = [
    ("locate", "point: vec3<f32>, normal: vec3<f32>", "u32"),
    ("pdf", "region: u32, normal: vec3<f32>, wi: vec3<f32>", "f32"),
    ("sample", "region: u32, normal: vec3<f32>, u: vec2<f32>", "GuideSample"),
    ("learn", "region: u32, normal: vec3<f32>, wi: vec3<f32>, goal: f32, pdf: f32", ""),
    ("integral", "region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32", "f32"),
    ("rebuild", "region: u32", ""),
];

/// The guide dispatch: for each hook, `guide_NAME` calling the hook of the structure
/// `params.guide_kind` names (the first structure's where it names none).
fn guide_dispatch() -> String {
    let mut source = String::from("// Generated from Rust (gpu/shader.rs): the guide dispatch.\n");
    let [first, others @ ..] = &GUIDE_SHADERS;
    for (name, parameters, returns) in GUIDE_HOOKS {
        let arguments: Vec<&str> = parameters.split(", ").filter_map(|p| p.split(':').next()).collect();
        let arguments = arguments.join(", ");
        let (arrow, give, done) = if returns.is_empty() {
            (String::new(), "", " return;")
        } else {
            (format!(" -> {returns}"), "return ", "")
        };
        let _ = writeln!(source, "fn guide_{name}({parameters}){arrow} {{");
        for guide in others {
            let (constant, prefix) = (guide.constant, guide.prefix);
            let _ = writeln!(
                source,
                "    if (params.guide_kind == {constant}) {{ {give}{prefix}_{name}({arguments});{done} }}"
            );
        }
        let _ = writeln!(source, "    {give}{}_{name}({arguments});\n}}", first.prefix);
    }
    source
}

/// The WGSL constants that must equal Rust's codes, by name.
fn generated_constants() -> impl Iterator<Item = (&'static str, u32)> {
    [
        ("METHOD_PT", method_code(Method::Pt)),
        ("METHOD_NEE", method_code(Method::Nee)),
        ("METHOD_GUIDED", method_code(Method::Guided)),
        ("METHOD_GUIDED_NEE", method_code(Method::GuidedNee)),
        ("DIFFUSE", MATERIAL_DIFFUSE),
        ("CONDUCTOR", MATERIAL_CONDUCTOR),
        ("DIELECTRIC", MATERIAL_DIELECTRIC),
        ("THIN_DIELECTRIC", MATERIAL_THIN_DIELECTRIC),
        ("LEARNING_RATE_EXPONENTIAL", LEARNING_RATE_EXPONENTIAL),
        ("LEARNING_RATE_ENTRY_VISITS", LEARNING_RATE_ENTRY_VISITS),
        ("LEARNING_RATE_REGION_VISITS", LEARNING_RATE_REGION_VISITS),
        ("TREE_LEAF", FlatTree::LEAF),
        ("TREE_FLAG_PER_AXIS", TREE_FLAG_PER_AXIS),
        ("TREE_FLAG_FOLD", TREE_FLAG_FOLD),
        ("TREE_FLAG_COSINE", TREE_FLAG_COSINE),
    ]
    .into_iter()
    .chain(GUIDE_SHADERS.iter().map(|guide| (guide.constant, guide.code)))
}

/// The WGSL float constants that must equal Rust's, by name.
fn generated_float_constants() -> impl Iterator<Item = (&'static str, f32)> {
    let harmonics = SH_NAMES.into_iter().zip(SH_NORMALIZATION);
    harmonics.chain([("TREE_ALIGNED_COS", FlatTree::ALIGNED_COS), ("TREE_MIN_HALF_MASS", FlatTree::MIN_HALF_MASS)])
}

/// The names of guiding-core's spherical-harmonic normalisation constants (one each: a
/// change in their count fails to compile here).
const SH_NAMES: [&str; SH_NORMALIZATION.len()] = ["SH_K0", "SH_K1", "SH_K2", "SH_K3", "SH_K4"];

/// The whole shader.
pub(super) fn source() -> String {
    let mut source = String::from("// Generated from Rust (gpu/shader.rs): codes shared with the host.\n");
    // Writing to a String cannot fail.
    for (name, value) in generated_constants() {
        let _ = writeln!(source, "const {name}: u32 = {value}u;");
    }
    // `{:?}` prints the shortest decimal that reads back as the same f32.
    for (name, value) in generated_float_constants() {
        let _ = writeln!(source, "const {name}: f32 = {value:?};");
    }
    source.push('\n');
    source.push_str(Params::WGSL);
    source.push('\n');
    parts().for_each(|part| source.push_str(part));
    source.push_str(&guide_dispatch());
    source
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader parses and validates (naga, as wgpu does) without any GPU.
    #[test]
    fn the_shader_is_valid_wgsl() {
        use wgpu::naga;
        let source = source();
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        let mut validator =
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
        if let Err(e) = validator.validate(&module) {
            panic!("{}", e.emit_to_string(&source));
        }
        let entry_points: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(entry_points, ["sample_guide", "rebuild", "trace"]);
    }

    /// No file defines a constant the host generates (it would clash, or drift).
    #[test]
    fn generated_constants_are_defined_nowhere_else() {
        let names = generated_constants().map(|(name, _)| name);
        for name in names.chain(generated_float_constants().map(|(name, _)| name)) {
            let definition = format!("const {name}:");
            assert!(parts().all(|part| !part.contains(&definition)), "{name} is defined in a shader file");
        }
        assert!(source().contains("const SH_K0: f32 = 0.282095;"), "{}", &source()[..800]);
        assert!(parts().all(|part| !part.contains("struct Params")), "Params is declared in a shader file");
        for (hook, _, _) in GUIDE_HOOKS {
            let dispatch = format!("fn guide_{hook}(");
            assert!(parts().all(|part| !part.contains(&dispatch)), "guide_{hook} is defined in a shader file");
        }
    }

    /// Every field of the generated `Params` sits at the offset WGSL's uniform layout
    /// gives it, and the block has the size the shader expects: the bytes the host
    /// uploads are read field by field as written.
    #[test]
    fn params_layout_matches_wgsl() {
        use wgpu::naga;
        let source = source();
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (handle, ty) = module.types.iter().find(|(_, ty)| ty.name.as_deref() == Some("Params")).unwrap();
        let naga::TypeInner::Struct { members, span } = &ty.inner else { panic!("Params is not a struct") };
        let wgsl: Vec<(&str, usize)> =
            members.iter().map(|m| (m.name.as_deref().unwrap_or(""), m.offset as usize)).collect();
        assert_eq!(wgsl, Params::OFFSETS);
        assert_eq!(*span as usize, std::mem::size_of::<Params>());
        assert_eq!(layouter[handle].size as usize, std::mem::size_of::<Params>());
    }
}
