//! The pbrt-v3 and Mitsuba readers: small scenes written here load with the camera,
//! materials, textures and lights they describe; `convert` writes JSON that renders the
//! same image; bad files are errors naming the file and line.

mod support;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use reference_tracer::material::Surface;
use reference_tracer::scene::Scene;

fn write(folder: &Path, name: &str, text: &str) -> PathBuf {
    let path = folder.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A 2×2 PNG: red, green over blue, transparent white.
fn write_png(path: &Path) {
    let pixels = [255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 0];
    image::RgbaImage::from_raw(2, 2, pixels.to_vec()).unwrap().save(path).unwrap();
}

const PBRT_SCENE: &str = r#"# A room corner lit by a quad, seen by pbrt's left-handed camera.
LookAt 0 1 4  0 1 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "image" "integer xresolution" [ 32 ] "integer yresolution" [ 16 ]
Sampler "random" "integer pixelsamples" 4
PixelFilter "triangle" "float xwidth" [ 1 ] "float ywidth" [ 1 ]
WorldBegin
  Texture "checks" "spectrum" "checkerboard" "float uscale" [4] "float vscale" [4]
      "rgb tex1" [0.2 0.2 0.2] "rgb tex2" [0.8 0.8 0.8]
  MakeNamedMaterial "Floor" "string type" [ "matte" ] "texture Kd" [ "checks" ]
  MakeNamedMaterial "Steel" "string type" [ "metal" ] "rgb eta" [ 2.9 2.9 2.6 ] "rgb k" [ 3.0 2.9 2.8 ]
      "float roughness" [ 0.1 ] "bool remaproughness" [ "false" ]
  MakeNamedMaterial "Glass" "string type" [ "glass" ] "float index" [ 1.33 ]
  NamedMaterial "Floor"
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -2 0 -2  2 0 -2  2 0 2  -2 0 2 ] "float uv" [ 0 0 1 0 1 1 0 1 ]
  AttributeBegin
    NamedMaterial "Steel"
    Translate 1 0 0
    Scale 0.5 0.5 0.5
    Shape "trianglemesh" "integer indices" [ 0 1 2 ] "point P" [ 0 0 0  1 0 0  0 1 0 ]
  AttributeEnd
  AttributeBegin
    NamedMaterial "Glass"
    Shape "trianglemesh" "integer indices" [ 0 1 2 ] "point P" [ -1 0 0  -1 1 0  -1.5 0 0.5 ]
  AttributeEnd
  AttributeBegin
    AreaLightSource "diffuse" "rgb L" [ 10 10 10 ]
    # Wound to face up; the normals make it face down, as pbrt decides.
    Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
        "point P" [ -0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5 ]
        "normal N" [ 0 -1 0  0 -1 0  0 -1 0  0 -1 0 ]
  AttributeEnd
WorldEnd
"#;

#[test]
fn a_pbrt_scene_loads_with_its_camera_materials_and_light() {
    let folder = support::temp_folder("import-pbrt");
    let path = write(&folder, "scene.pbrt", PBRT_SCENE);
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangles.len(), 2 + 1 + 1 + 2);
    assert_eq!((scene.camera.width, scene.camera.height), (32, 16));
    // The light faces down, the way its normals say, not its winding.
    assert_eq!(scene.lights.len(), 2);
    let light = scene.lights.light_of_triangle(4).map(|_| 4).unwrap();
    assert!(scene.normals[light].y < -0.99, "{:?}", scene.normals[light]);
    // pbrt's image right is up × forward: looking down −z with +y up, the left edge of
    // the picture looks towards +x.
    let left = scene.camera.ray(Vec2::new(0.0, 8.0));
    assert!(left.direction.x > 0.0, "{:?}", left.direction);
    // fov spans the shorter axis (y here).
    let top = scene.camera.ray(Vec2::new(16.0, 0.0)).direction;
    assert!((top.y.atan2(-top.z).to_degrees() - 20.0).abs() < 0.01);
    // The checkerboard textures the floor; metal keeps its index; glass its ior.
    let floor = scene.material_at(0, Vec2::new(0.05, 0.05)).0;
    let Surface::Diffuse { albedo } = floor.surface else { panic!("{floor:?}") };
    assert!(albedo == Vec3::splat(0.2) || albedo == Vec3::splat(0.8), "{albedo}");
    let steel = scene.material(2);
    assert!(matches!(steel.surface, Surface::Conductor { alpha, ior: Some(_), .. } if (alpha - 0.1).abs() < 1e-6));
    assert_eq!(scene.material(3).surface, Surface::Dielectric { ior: 1.33 });
    // The transform moved and scaled the steel triangle.
    let steel_triangle = scene.triangles[2];
    assert!((steel_triangle.vertices[1] - Vec3::new(1.5, 0.0, 0.0)).length() < 1e-6);
    assert!(scene.warnings.iter().any(|w| w.contains("PixelFilter")), "{:?}", scene.warnings);
}

const MITSUBA_SCENE: &str = r#"<?xml version="1.0" encoding="utf-8"?>
<scene version="0.5.0">
  <integrator type="path"><integer name="maxDepth" value="8"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="toWorld"><lookat origin="0, 1, 4" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="20"/></film>
  </sensor>
  <texture type="bitmap" id="Leaf"><string name="filename" value="leaf.png"/></texture>
  <bsdf type="twosided" id="Wood">
    <bsdf type="roughplastic">
      <float name="alpha" value="0.2"/>
      <float name="intIOR" value="1.5"/>
      <boolean name="nonlinear" value="true"/>
      <rgb name="diffuseReflectance" value="0.5, 0.3, 0.2"/>
    </bsdf>
  </bsdf>
  <bsdf type="mask" id="Leaves">
    <ref name="opacity" id="Leaf"/>
    <bsdf type="twosided"><bsdf type="diffuse"><ref name="reflectance" id="Leaf"/></bsdf></bsdf>
  </bsdf>
  <shape type="obj">
    <string name="filename" value="floor.obj"/>
    <boolean name="faceNormals" value="true"/>
    <ref id="Wood"/>
  </shape>
  <shape type="rectangle">
    <transform name="toWorld"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="2"/></transform>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf></bsdf>
    <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
  </shape>
  <shape type="disk">
    <transform name="toWorld"><translate x="1" y="0.5"/></transform>
    <ref id="Leaves"/>
  </shape>
</scene>
"#;

const FLOOR_OBJ: &str = "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 3 2\nf 1 4 3\n";

fn mitsuba_folder(name: &str) -> (PathBuf, PathBuf) {
    let folder = support::temp_folder(name);
    write(&folder, "floor.obj", FLOOR_OBJ);
    write_png(&folder.join("leaf.png"));
    let path = write(&folder, "scene.xml", MITSUBA_SCENE);
    (folder, path)
}

#[test]
fn a_mitsuba_scene_loads_with_its_camera_materials_and_light() {
    let (_folder, path) = mitsuba_folder("import-mitsuba");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((scene.camera.width, scene.camera.height), (40, 20));
    // Mitsuba's image right is forward × up: looking down −z, the left edge looks to −x.
    assert!(scene.camera.ray(Vec2::new(0.0, 10.0)).direction.x < 0.0);
    // fov 60 along x.
    let right = scene.camera.ray(Vec2::new(40.0, 10.0)).direction;
    assert!((right.x.atan2(-right.z).to_degrees() - 30.0).abs() < 0.01, "{right}");
    // The rectangle, rotated +90° about x, faces −y: a light looking down.
    assert_eq!(scene.lights.len(), 2);
    for light in 2..4 {
        assert!(scene.lights.light_of_triangle(light).is_some());
        assert!(scene.normals[light as usize].y < -0.99, "{:?}", scene.normals[light as usize]);
    }
    let wood = scene.material(0);
    let Surface::Plastic(plastic) = wood.surface else { panic!("{wood:?}") };
    assert!((plastic.ior - 1.5).abs() < 1e-3 && (plastic.alpha - 0.2).abs() < 1e-6, "{plastic:?}");
    // The disk is masked by the PNG's alpha: opaque at the red texel, clear at the last.
    let disk = scene.triangles.len() as u32 - 1;
    let leaf = scene.material(disk);
    assert!(leaf.opacity_texture.is_some() && leaf.albedo_texture.is_some());
    assert!(scene.has_masks());
    let texture = &scene.textures[leaf.opacity_texture.unwrap() as usize];
    assert_eq!(texture.opacity(Vec2::new(0.25, 0.75)), 1.0);
    assert_eq!(texture.opacity(Vec2::new(0.75, 0.25)), 0.0);
    let red = texture.eval(Vec2::new(0.25, 0.75));
    assert!((red - Vec3::X).length() < 1e-6, "{red}");
}

fn render_mean(path: &Path) -> Vec3 {
    let settings = support::settings(reference_tracer::integrator::Method::Nee);
    support::render_image(path, settings, None, 4, 3).0.mean()
}

#[test]
fn converted_scenes_render_exactly_like_the_originals() {
    let folder = support::temp_folder("import-convert");
    let pbrt = write(&folder, "scene.pbrt", PBRT_SCENE);
    let out = folder.join("converted/room.json");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    reference_tracer::import::convert(&pbrt, &out).unwrap();
    assert_eq!(render_mean(&pbrt), render_mean(&out));

    let (folder, xml) = mitsuba_folder("import-convert-xml");
    let out = folder.join("elsewhere/room.json");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    reference_tracer::import::convert(&xml, &out).unwrap();
    let json = std::fs::read_to_string(&out).unwrap();
    assert!(json.contains("../floor.obj") && json.contains("../leaf.png"), "files rebased: {json}");
    assert_eq!(render_mean(&xml), render_mean(&out));
}

/// Loads `text` as `name` and returns the error, which must name the file and `line`.
fn error_of(name: &str, text: &str, line: usize) -> String {
    let (folder, _) = mitsuba_folder(&format!("import-error-{}", name.replace('.', "-")));
    let path = write(&folder, name, text);
    let error = Scene::load(&path).err().unwrap_or_else(|| panic!("{name}: must be rejected")).to_string();
    assert!(error.contains(name), "`{error}` does not name the file");
    assert!(error.contains(&format!("line {line}")), "`{error}` does not name line {line}");
    error
}

#[test]
fn bad_pbrt_files_name_the_line() {
    let scene =
        |world: &str| format!("LookAt 0 1 4 0 1 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n{world}\nWorldEnd\n");
    let e = error_of("a.pbrt", &scene("Frobnicate 1 2 3"), 4);
    assert!(e.contains("Frobnicate"));
    let e = error_of("b.pbrt", &scene("NamedMaterial \"nothing\""), 4);
    assert!(e.contains("unknown material"));
    let e = error_of(
        "c.pbrt",
        &scene("MakeNamedMaterial \"m\" \"string type\" \"matte\" \"spectrum Kd\" [ 300 0.5 800 0.5 ]"),
        4,
    );
    assert!(e.contains("spectral"));
    let e = error_of("d.pbrt", &scene("Shape \"sphere\" \"float radius\" 1"), 4);
    assert!(e.contains("sphere"));
    let e = error_of("e.pbrt", &scene("Shape \"trianglemesh\" \"point P\" [ 0 0 0 1 0 0 0 1 oops ]"), 4);
    assert!(e.contains("oops"));
    let e = error_of(
        "f.pbrt",
        &scene("AttributeBegin\nMakeNamedMaterial \"m\" \"string type\" \"matte\" \"texture Kd\" \"none\""),
        5,
    );
    assert!(e.contains("unknown texture"));
    error_of("g.pbrt", &scene("Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png"), 4);
    let e = error_of("h.pbrt", &scene("LightSource \"point\" \"rgb I\" [1 1 1]"), 4);
    assert!(e.contains("point"));
}

#[test]
fn bad_mitsuba_files_name_the_line() {
    let e = error_of("a.xml", "<scene version=\"0.5.0\">\n<shape type=\"obj\">\n</scene>", 3);
    assert!(e.contains("malformed XML"));
    let with = |body: &str| {
        format!(
            "<scene version=\"0.5.0\">\n<sensor type=\"perspective\"><float name=\"fov\" value=\"45\"/></sensor>\n{body}\n</scene>"
        )
    };
    let e = error_of("b.xml", &with("<bsdf type=\"velvet\" id=\"x\"/>"), 3);
    assert!(e.contains("velvet"));
    let e = error_of("c.xml", &with("<shape type=\"obj\"><ref id=\"nothing\"/></shape>"), 3);
    assert!(e.contains("unknown bsdf"));
    let e = error_of("d.xml", &with("<shape type=\"rectangle\">\n<float name=\"x\" value=\"nan\"/></shape>"), 4);
    assert!(e.contains("not one finite number"));
    let e = error_of("e.xml", &with("<emitter type=\"point\"/>"), 3);
    assert!(e.contains("point"));
    let e = error_of("f.xml", &with("<shape type=\"obj\"><string name=\"filename\" value=\"$mesh\"/></shape>"), 3);
    assert!(e.contains("$parameters"));
}
