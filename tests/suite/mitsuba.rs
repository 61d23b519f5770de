//! Mitsuba 3 XML scenes: the shipped Cornell box, each convention the loader maps
//! (depth, sidedness, field of view, transforms) against numbers worked out by hand,
//! PLY shapes, and an error naming the element and line for what is not supported.
//! The image comparison with Mitsuba itself is in docs/mitsuba.md (it needs Mitsuba).

use crate::seeds::{assert_agree, runs};
use std::path::{Path, PathBuf};
use warpray::cast::BvhCaster;
use warpray::filter::Filter;
use warpray::glam::Vec3;
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{SceneDesc, load_scene, parse_mitsuba};

fn parse(xml: &str) -> warpray::error::Result<SceneDesc> {
    parse_mitsuba(Path::new("test.xml"), xml)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("warpray-mitsuba-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_shipped_cornell_box_loads_as_mitsuba_describes_it() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/mitsuba-cbox.xml");
    let desc = load_scene(&path).unwrap();
    let (scene, s) = (&desc.scene, &desc.settings);
    // Six rectangles and two cubes.
    assert_eq!(scene.triangle_count(), 6 * 2 + 2 * 12);
    assert_eq!((s.width, s.height, s.spp), (Some(256), Some(256), Some(64)), "{s:?}");
    // Mitsuba's max_depth 8 counts segments: 7 scattering events here.
    assert_eq!(s.max_depth, Some(7));
    assert_eq!(s.integrator.as_deref(), Some("path"));
    assert_eq!(s.filter, Some(Filter::mitsuba_gaussian()));
    // Mitsuba's film splats camera samples and normalises by the summed weights.
    assert_eq!(s.filter_mode, Some(warpray::filter::FilterMode::Splat));
    let cam = scene.camera;
    assert!((cam.position - Vec3::new(0.0, 0.0, 3.9)).length() < 1e-6);
    assert!((cam.forward - Vec3::NEG_Z).length() < 1e-6 && (cam.right - Vec3::X).length() < 1e-6);
    // fov_axis "smaller" on a square film is the vertical field of view.
    assert!((cam.vfov_deg - 39.3077).abs() < 1e-4);
    // Opaque BSDFs outside `twosided` are one-sided; only the light emits.
    assert!(scene.two_sided.iter().all(|t| !t));
    let emitters: Vec<Vec3> = scene.emission.iter().copied().filter(|e| *e != Vec3::ZERO).collect();
    assert_eq!(emitters, vec![Vec3::new(18.387, 13.9873, 6.75357)]);
    // The light: 0.46 x 0.38 at y = 0.99, facing down.
    let light: Vec<u32> = (0..scene.triangle_count() as u32).filter(|&t| scene.emission_of(t) != Vec3::ZERO).collect();
    let area: f32 = light.iter().map(|&t| 0.5 * scene.normal(t).length()).sum();
    assert!((area - 0.46 * 0.38).abs() < 1e-5, "{area}");
    assert!(light.iter().all(|&t| scene.normal(t).normalize().dot(Vec3::NEG_Y) > 0.9999));
    // The large box: Mitsuba's translate · rotate(y, 18.25°) · scale(0.3, 0.61, 0.3),
    // reaching from y = −1.01 (below the floor, as in Mitsuba) to 0.21.
    let b = scene.bounds();
    let (lo, hi) = (Vec3::new(-1.0, -1.01, -1.0), Vec3::ONE);
    assert!((b.min - lo).length() < 1e-5 && (b.max - hi).length() < 1e-5, "{b:?}");
    let top = scene.positions.iter().map(|p| p.y).filter(|y| *y < 0.9).fold(f32::MIN, f32::max);
    assert!((top - (-0.4 + 0.61)).abs() < 1e-5, "{top}");
}

/// A quad of size 2 facing +z at z = 0, a point light and a camera on one side.
fn plane_scene(bsdf: &str, light_z: f32, camera_z: f32, max_depth: i32) -> String {
    format!(
        r#"<scene version="3.0.0">
            <integrator type="path"><integer name="max_depth" value="{max_depth}"/></integrator>
            <sensor type="perspective">
                <float name="fov" value="2"/>
                <transform name="to_world"><lookat origin="0, 0, {camera_z}" target="0, 0, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
                    <rfilter type="box"/></film>
            </sensor>
            <shape type="rectangle">{bsdf}</shape>
            <emitter type="point"><point name="position" value="0, 0, {light_z}"/>
                <rgb name="intensity" value="2, 2, 2"/></emitter>
        </scene>"#
    )
}

fn image(desc: &SceneDesc, integrator: IntegratorKind, spp: u32) -> Vec<Vec3> {
    let s = &desc.settings;
    let opts = RenderOptions {
        width: 8,
        height: 8,
        budget: Budget::Samples(spp),
        max_depth: s.max_depth.unwrap(),
        filter: s.filter.unwrap(),
        integrator,
        ..Default::default()
    };
    let (film, _) = render(&desc.scene, &BvhCaster::new(&desc.scene), &opts, |_, _| true).unwrap();
    assert_eq!(film.rejected, 0);
    film.mean()
}

fn centre_pixel(desc: &SceneDesc) -> f32 {
    image(desc, IntegratorKind::Path, 4)[4 * 8 + 4].y
}

#[test]
fn one_sided_and_two_sided_bsdfs_and_max_depth_follow_mitsuba() {
    let diffuse = r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>"#;
    let two = r#"<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>"#;
    // Point light of intensity 2 at distance 2 on the normal: E = 2 / 4, L = (0.5/π) E.
    // The centre pixel sees the plane within 0.022 of the axis, where E falls by
    // under 0.02 %.
    let want = 0.5 / std::f32::consts::PI * 2.0 / 4.0;
    let front = centre_pixel(&parse(&plane_scene(diffuse, 2.0, 5.0, 2)).unwrap());
    assert!((front / want - 1.0).abs() < 2e-3, "{front} vs {want}");
    // Seen and lit from behind: black when one-sided, the same value when two-sided.
    assert_eq!(centre_pixel(&parse(&plane_scene(diffuse, -2.0, -5.0, 2)).unwrap()), 0.0);
    let back = centre_pixel(&parse(&plane_scene(two, -2.0, -5.0, 2)).unwrap());
    assert!((back / want - 1.0).abs() < 2e-3, "{back} vs {want}");
    // Every integrator sees the back of a one-sided surface as black (light paths
    // that reach it from behind carry nothing either); BDPT, which mostly samples
    // the light from the surface, agrees with the value of the two-sided one.
    // A second, two-sided wall behind the camera gives paths that bounce off the back
    // of the one-sided plane somewhere to go (and a light to reach) if an integrator
    // let them through.
    let wall = r#"<shape type="rectangle"><transform name="to_world"><scale value="20"/><translate z="-6"/></transform>
        <bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape></scene>"#;
    for kind in
        [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc, IntegratorKind::Cis]
    {
        let xml = plane_scene(diffuse, -2.0, -5.0, 5).replace("</scene>", wall);
        let black = image(&parse(&xml).unwrap(), kind, 16);
        assert!(black.iter().all(|p| *p == Vec3::ZERO), "{kind:?}: one-sided back is not black");
    }
    let bdpt = image(&parse(&plane_scene(two, -2.0, -5.0, 2)).unwrap(), IntegratorKind::Bdpt, 64)[4 * 8 + 4].y;
    assert!((bdpt / want - 1.0).abs() < 1e-2, "bdpt {bdpt} vs {want}");
    // max_depth 1 (Mitsuba) shows emitters only: the lit plane is black.
    let desc = parse(&plane_scene(diffuse, 2.0, 5.0, 1)).unwrap();
    assert_eq!(desc.settings.max_depth, Some(0));
    assert_eq!(centre_pixel(&desc), 0.0);
    // -1 is "no limit".
    assert_eq!(parse(&plane_scene(diffuse, 2.0, 5.0, -1)).unwrap().settings.max_depth, Some(62));
}

#[test]
fn field_of_view_axes_and_transforms_match_hand_computed_values() {
    let scene = |fov_axis: &str, transform: &str| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="60"/>
                <string name="fov_axis" value="{fov_axis}"/>
                <film type="hdrfilm"><integer name="width" value="200"/><integer name="height" value="100"/></film></sensor>
               <shape type="rectangle"><transform name="to_world">{transform}</transform>
                <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></scene>"#
        )
    };
    let t30 = (30f32).to_radians().tan();
    let vfov = |r: f32| 2.0 * (t30 * r).atan().to_degrees();
    for (axis, ratio) in
        [("x", 0.5), ("y", 1.0), ("smaller", 1.0), ("larger", 0.5), ("diagonal", 100.0 / 50_000f32.sqrt())]
    {
        let d = parse(&scene(axis, "")).unwrap();
        assert!((d.scene.camera.vfov_deg - vfov(ratio)).abs() < 1e-3, "{axis}: {}", d.scene.camera.vfov_deg);
    }
    // scale, then rotate 90° about z, then translate: corner (1, 1, 0) -> (2, 3, 0) ->
    // (-3, 2, 0) -> (-2, 2, 5). A 16-number matrix (row-major) does the same.
    let steps = r#"<scale x="2" y="3"/><rotate z="1" angle="90"/><translate value="1 0 5"/>"#;
    let matrix = r#"<matrix value="0 -3 0 1  2 0 0 0  0 0 1 5  0 0 0 1"/>"#;
    for t in [steps, matrix] {
        let d = parse(&scene("x", t)).unwrap();
        assert!(d.scene.positions.iter().any(|p| (*p - Vec3::new(-2.0, 2.0, 5.0)).length() < 1e-5), "{t}");
        // The rectangle still faces +z (rotation about z keeps it).
        assert!(d.scene.normal(0).normalize().dot(Vec3::Z) > 0.9999);
    }
}

#[test]
fn ply_and_obj_shapes_load_with_their_transform() {
    let dir = scratch("meshes");
    std::fs::write(
        dir.join("tri.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    // An OBJ naming an MTL that does not exist: Mitsuba ignores mtllib, so do we.
    std::fs::write(dir.join("tri.obj"), "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let xml = r#"<scene version="3.0.0">
        <shape type="ply"><string name="filename" value="tri.ply"/>
            <transform name="to_world"><translate z="2"/></transform>
            <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
        <shape type="obj"><string name="filename" value="tri.obj"/><boolean name="flip_normals" value="true"/></shape>
        </scene>"#;
    let path = dir.join("s.xml");
    std::fs::write(&path, xml).unwrap();
    let d = load_scene(&path).unwrap();
    assert_eq!(d.scene.triangle_count(), 2);
    assert!(d.scene.vertices(0).iter().all(|p| p.z == 2.0));
    // flip_normals reverses the winding: the OBJ triangle faces -z.
    assert!(d.scene.normal(1).z < 0.0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn unsupported_or_bad_input_is_an_error_naming_the_element_and_line() {
    let wrap = |body: &str| format!("<scene version=\"3.0.0\">\n{body}\n</scene>");
    let rect = |bsdf: &str| format!("<shape type=\"rectangle\">\n{bsdf}\n</shape>");
    let cases = [
        (wrap("<emitter type=\"envmap\"/>"), "test.xml:2", "envmap"),
        (wrap(&rect("<bsdf type=\"roughconductor\"/>")), "test.xml:3", "beckmann"),
        (
            wrap(&rect("<bsdf type=\"diffuse\"><float name=\"roughness\" value=\"1\"/></bsdf>")),
            "test.xml:3",
            "'roughness'",
        ),
        (
            wrap(&rect("<bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\"/></bsdf>")),
            "test.xml:3",
            "textures",
        ),
        (
            wrap(&rect("<bsdf type=\"diffuse\"><spectrum name=\"reflectance\" value=\"400:0.1, 700:0.5\"/></bsdf>")),
            "test.xml:3",
            "spectra",
        ),
        (wrap(&rect("<ref id=\"nothing\"/>")), "test.xml:3", "nothing"),
        (wrap("<shape type=\"cylinder\"/>"), "test.xml:2", "cylinder"),
        (
            wrap(&rect("<bsdf type=\"plastic\"><string name=\"int_ior\" value=\"air\"/></bsdf>")),
            "test.xml:3",
            "two different indices",
        ),
        (
            wrap(&rect("<bsdf type=\"diffuse\"><point name=\"reflectance\" value=\"1, 0, 0\"/></bsdf>")),
            "test.xml:3",
            "expected a colour",
        ),
        (
            wrap("<integrator type=\"path\"><integer name=\"max_depth\" value=\"0\"/></integrator>"),
            "test.xml:2",
            "max_depth",
        ),
        (
            wrap("<integrator type=\"path\"><integer name=\"max_depth\" value=\"$depth\"/></integrator>"),
            "test.xml:2",
            "$depth",
        ),
        (
            wrap("<sensor type=\"perspective\"><transform name=\"to_world\"><scale x=\"-1\"/></transform></sensor>"),
            "test.xml:2",
            "mirrors",
        ),
        (
            wrap("<shape type=\"rectangle\"><transform name=\"to_world\"><translate x=\"nan\"/></transform></shape>"),
            "test.xml:2",
            "not finite",
        ),
        (
            // A step inside a step was ignored without a word (the held-out corpus).
            wrap(
                "<shape type=\"rectangle\"><transform name=\"to_world\"><translate x=\"1\">\n<scale value=\"2\"/></translate></transform></shape>",
            ),
            "test.xml:3",
            "a step takes no elements",
        ),
        (wrap("<shape type=\"rectangle\">"), "test.xml:3", "malformed XML"),
        (wrap("<include filename=\"other.xml\"/>"), "test.xml:2", "<include"),
        (
            wrap(
                "<sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"1e9\"/></film></sensor>",
            ),
            "test.xml:2",
            "width",
        ),
    ];
    for (xml, at, what) in cases {
        let e = parse(&xml).err().map(|e| e.to_string()).unwrap_or_else(|| "no error".into());
        assert!(e.contains(at) && e.contains(what), "{what}: {e}");
    }
}

/// Every pixel of a black enclosure that emits `Le` inward sees exactly `Le`, the
/// border pixels too: with a Gaussian filter their footprint reaches past the image,
/// and light tracing and BDPT's light-tracing strategy must splat there as well.
#[test]
fn gaussian_filtered_images_are_unbiased_up_to_the_border() {
    let (v, f) = crate::common::icosphere(2);
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| [v[t[0] as usize], v[t[2] as usize], v[t[1] as usize]]).collect();
    let mut scene = crate::common::scene_from_triangles(&tris);
    scene.materials[0] = warpray::scene::Material::Diffuse { albedo: Vec3::ZERO };
    scene.emission[0] = Vec3::ONE;
    scene.camera = warpray::scene::Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y, 60.0);
    let caster = BvhCaster::new(&scene);
    let (w, h) = (12u32, 12u32);
    for integrator in [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt] {
        let (mut border, mut all) = (Vec::new(), Vec::new());
        for seed in 0..8 {
            let opts = RenderOptions {
                width: w,
                height: h,
                // Light tracing reaches the small image with few of its paths.
                budget: Budget::Samples(if integrator == IntegratorKind::Light { 1024 } else { 64 }),
                max_depth: 1,
                seed,
                integrator,
                filter: Filter::mitsuba_gaussian(),
                ..Default::default()
            };
            let (film, _) = render(&scene, &caster, &opts, |_, _| true).unwrap();
            let img = film.mean();
            let edge = |i: usize| {
                let (x, y) = (i as u32 % w, i as u32 / w);
                x == 0 || y == 0 || x == w - 1 || y == h - 1
            };
            let ring: Vec<f64> = (0..img.len()).filter(|&i| edge(i)).map(|i| img[i].y as f64).collect();
            border.push(ring.iter().sum::<f64>() / ring.len() as f64);
            all.push(film.image_mean().y as f64);
        }
        for (what, m) in [("border", &border), ("image", &all)] {
            let (mean, se) = crate::common::statistics(m);
            let z = (mean - 1.0) / se.max(1e-9);
            assert!(z.abs() < 5.0 && se < 0.005, "{integrator:?} {what}: {mean:.5} ± {se:.5} (z = {z:.1})");
        }
    }
}

#[test]
fn scene_files_and_the_command_line_name_a_filter() {
    let text = "base = \"cornell\"\n[render]\nfilter = \"gaussian:0.5:1.5\"\n";
    let d = warpray::scene::parse_scene_file(Path::new("f.toml"), text).unwrap();
    assert_eq!(d.settings.filter, Some(Filter::gaussian(0.5, 1.5).unwrap()));
    let text = "base = \"cornell\"\n[render]\nfilter_mode = \"splat\"\n";
    let d = warpray::scene::parse_scene_file(Path::new("f.toml"), text).unwrap();
    assert_eq!(d.settings.filter_mode, Some(warpray::filter::FilterMode::Splat));
    let bad = warpray::scene::parse_scene_file(Path::new("f.toml"), "[render]\nfilter_mode = \"blur\"\n").unwrap_err();
    assert!(bad.to_string().contains("f.toml:2") && bad.to_string().contains("blur"), "{bad}");
    let bad = warpray::scene::parse_scene_file(Path::new("f.toml"), "[render]\nfilter = \"tent\"\n").unwrap_err();
    assert!(bad.to_string().contains("f.toml:2") && bad.to_string().contains("tent"), "{bad}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_warpray"))
        .args(["render", "--filter", "gaussian:0:2", "--spp", "1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("stddev"), "{}", String::from_utf8_lossy(&out.stderr));
}

mod mangled {
    //! Damaged files never panic the loader: random edits of the shipped XML and random
    //! bytes in a PLY it names each give a scene or a typed error.
    use super::*;
    use proptest::prelude::*;

    const CBOX: &str = include_str!("../../assets/scenes/mitsuba-cbox.xml");

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn edited_xml_gives_a_scene_or_an_error(edits in prop::collection::vec((0usize..4000, 0u8..4, "[ -~]{0,6}"), 1..6)) {
            let mut text = CBOX.to_string();
            for (at, kind, insert) in edits {
                let mut at = at % (text.len() + 1);
                while !text.is_char_boundary(at) {
                    at -= 1;
                }
                let end = (at + insert.len().max(1)).min(text.len());
                let end = (end..=text.len()).find(|&e| text.is_char_boundary(e)).unwrap_or(text.len());
                match kind {
                    0 => text.insert_str(at, &insert),
                    1 => text.replace_range(at..end, ""),
                    2 => text.replace_range(at..end, &insert),
                    // Numbers are where the values live: swap one for something odd.
                    _ => {
                        if let Some(i) = text[at..].find(|c: char| c.is_ascii_digit()) {
                            let odd = ["nan", "-1", "1e39", "0", "inf", "-0", "99999999999"][insert.len() % 7];
                            text.replace_range(at + i..at + i + 1, odd);
                        }
                    }
                }
            }
            let _ = parse(&text);
        }

        #[test]
        fn random_ply_bytes_give_a_scene_or_an_error(body in prop::collection::vec(any::<u8>(), 0..400), ascii in any::<bool>(), count in prop_oneof![0u64..6, 0u64..1_000_000_000_000]) {
            let dir = scratch("fuzz-ply");
            let format = if ascii { "ascii" } else { "binary_little_endian" };
            let mut bytes = format!(
                "ply\nformat {format} 1.0\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\n\
                 element face {count}\nproperty list uchar int vertex_indices\nend_header\n"
            )
            .into_bytes();
            if ascii {
                // Plausible tokens, so that many files parse and reach the checks on
                // what they say (short faces, indices out of range, odd numbers).
                const TOKENS: [&str; 10] = ["0", "1", "2", "3", "4", "-1", "nan", "1e40", "\n", " "];
                for b in &body {
                    bytes.extend_from_slice(TOKENS[*b as usize % TOKENS.len()].as_bytes());
                    bytes.push(b' ');
                }
            } else {
                bytes.extend_from_slice(&body);
            }
            std::fs::write(dir.join("m.ply"), &bytes).unwrap();
            let xml = r#"<scene version="3.0.0"><shape type="ply"><string name="filename" value="m.ply"/></shape></scene>"#;
            let path = dir.join("s.xml");
            std::fs::write(&path, xml).unwrap();
            let _ = load_scene(&path);
        }
    }
}

#[test]
fn deeply_nested_twosided_bsdfs_are_an_error_not_a_crash() {
    // 30,000 nested twosided wrappers overflowed the stack (the parser recursed once per
    // level); now the second level is an error naming the element's line.
    for depth in [2, 30_000] {
        let bsdf = format!(
            "{}<bsdf type=\"diffuse\"/>{}",
            "<bsdf type=\"twosided\">\n".repeat(depth),
            "</bsdf>".repeat(depth)
        );
        let xml = format!(r#"<scene version="3.0.0"><shape type="rectangle">{bsdf}</shape></scene>"#);
        let e = parse(&xml).err().unwrap_or_else(|| panic!("depth {depth} accepted")).to_string();
        assert!(e.contains("twosided <bsdf> inside a twosided") && e.contains("test.xml:2"), "{e}");
    }
}

#[test]
fn dielectrics_take_mitsubas_ior_names_as_documented() {
    // docs/scene-format.md: `int_ior`, `ext_ior` are numbers or Mitsuba's names.
    let glass = |ior: &str| {
        let xml = format!(
            r#"<scene version="3.0.0"><shape type="rectangle"><bsdf type="dielectric">{ior}</bsdf></shape></scene>"#
        );
        parse(&xml).map(|d| d.scene.materials[0])
    };
    let by_name = glass(r#"<string name="int_ior" value="bk7"/><string name="ext_ior" value="air"/>"#).unwrap();
    let by_number = glass(r#"<float name="int_ior" value="1.5046"/><float name="ext_ior" value="1.000277"/>"#).unwrap();
    assert_eq!(by_name, by_number);
    assert!(matches!(by_name, warpray::scene::Material::Glass { ior, .. } if (ior - 1.5046 / 1.000277).abs() < 1e-6));
    let e = glass(r#"<string name="int_ior" value="unobtainium"/>"#).unwrap_err().to_string();
    assert!(e.contains("unknown material 'unobtainium'") && e.contains("bk7"), "{e}");
    let e = glass(r#"<boolean name="int_ior" value="true"/>"#).unwrap_err().to_string();
    assert!(e.contains("a number or a <string> name"), "{e}");
}

#[test]
fn duplicate_ids_and_fractional_counts_are_errors() {
    // Silently, the later <bsdf> of an id won, and sample_count 1.5 became 1.
    let two = r#"<scene version="3.0.0"><bsdf type="diffuse" id="a"/>
<bsdf type="conductor" id="a"/></scene>"#;
    let e = parse(two).unwrap_err().to_string();
    assert!(e.contains("a second <bsdf id=\"a\">") && e.contains("test.xml:2"), "{e}");
    for (what, value) in [("sample_count", "1.5"), ("seed", "-3"), ("seed", "2.5")] {
        let xml = format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><sampler type="independent"><float name="{what}" value="{value}"/></sampler></sensor></scene>"#
        );
        let e = parse(&xml).unwrap_err().to_string();
        assert!(e.contains(&format!("{what} {value}")) && e.contains("whole number"), "{what} {value}: {e}");
    }
}

/// The heavy tier (README, docs/testing.md): tests that need many samples for their
/// power, run by CI and before a release rather than before every commit.
mod heavy {
    use super::*;

    /// On Mitsuba's own Cornell box (its one-sided BSDFs and light) every integrator
    /// agrees with BDPT over 16 seeds each: image means to a combined standard error of
    /// 0.18 % (a 1 % bias fails; the path tracer 0.25 %) and block by block (`seeds.rs`). With the box filter: under
    /// the file's Gaussian (radius 2) about twenty pixels around the light's edge carry most
    /// of the variance of a 32² image mean; the Gaussian itself is checked against a closed
    /// form in `gaussian_filtered_images_are_unbiased_up_to_the_border`.
    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn every_integrator_agrees_on_the_mitsuba_cornell_box() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/mitsuba-cbox.xml");
        let desc = load_scene(&path).unwrap();
        let caster = BvhCaster::new(&desc.scene);
        let image = |integrator: IntegratorKind, spp: u32, seed: u64| {
            let opts = RenderOptions {
                width: 32,
                height: 32,
                budget: Budget::Samples(spp),
                max_depth: desc.settings.max_depth.unwrap(),
                filter: Filter::Box,
                integrator,
                seed,
                ..Default::default()
            };
            let (film, _) = render(&desc.scene, &caster, &opts, |_, _| true).unwrap();
            assert_eq!(film.rejected, 0);
            film.mean()
        };
        let bdpt = runs("bdpt", 100, 32, 8, |seed| image(IntegratorKind::Bdpt, 16, seed));
        // The path tracer's image mean is the noisiest here: known to 0.15-0.18 % at 240 spp
        // per seed (a 1.5 % bias fails; `direct.rs` sees its light sampling to 0.1 %).
        for (kind, spp, precision) in [
            (IntegratorKind::Path, 240, 0.0025),
            (IntegratorKind::Light, 24, 0.0018),
            (IntegratorKind::Lvc, 6, 0.0018),
            (IntegratorKind::Cis, 8, 0.0018),
        ] {
            let r = runs(&format!("{kind:?}"), 1000, 32, 8, |seed| image(kind, spp, seed));
            eprintln!("{}", assert_agree(&r, &bdpt, precision));
        }
    }
}
