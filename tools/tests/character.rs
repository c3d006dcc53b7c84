//! Issue 24: the character scenes (scenes/character). `finger_quick`: a curved skin strip over a
//! finger's bone surface, flexing 40 degrees at a procedural joint, held by geodesic kernels
//! (lambda = 6 mm). Wrinkles form over the joint only, across the bend, in the kernels'
//! wavelength band. `cargo test --release -p skinsim-cli --test character -- --nocapture` prints the
//! figures.

use std::path::Path;

use glam::{DVec2, DVec3};
use skinsim::mesh::shading::vertex_normals;
use skinsim::scene;
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::row_peaks;

#[test]
fn the_finger_wrinkles_over_its_knuckle_at_the_kernel_wavelength() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/finger_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    let clock = std::time::Instant::now();
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none() && s.patches[0].outcome.converged, "frame {frame}: {:?}", s.patches[0]);
    }
    let per_frame = clock.elapsed().as_secs_f64() / built.scene.frames as f64;
    // The skin's height over the bone along the bone's normals (the skin is the bone's offset:
    // the same vertices in the same order), minus the offset.
    let (_, bone, faces) = sim.layer_surface("finger", "bone");
    let (uv, skin, _) = sim.layer_surface("finger", "skin");
    let normals = vertex_normals(&bone, &faces);
    let height: Vec<f64> =
        skin.iter().zip(&bone).zip(&normals).map(|((s, b), n)| (*s - *b).dot(*n) - 0.01875e-3).collect();
    // Wrinkled where the height swings: over the 30 mm joint zone, not on the straight ends.
    let swing = |keep: &dyn Fn(DVec2) -> bool| {
        let h: Vec<f64> = uv.iter().zip(&height).filter(|(u, _)| keep(**u)).map(|(_, h)| *h).collect();
        h.iter().fold(f64::NEG_INFINITY, |m, x| m.max(*x)) - h.iter().fold(f64::INFINITY, |m, x| m.min(*x))
    };
    let joint = swing(&|u| u.x.abs() < 0.010);
    let ends = swing(&|u| u.x.abs() > 0.020);
    // Spectrum of the rows along the finger (lines of one angle) over the joint zone.
    let (pos, mat): (Vec<DVec3>, Vec<DVec2>) =
        uv.iter().zip(&height).filter(|(u, _)| u.x.abs() < 0.015).map(|(u, h)| (DVec3::new(0.0, 0.0, *h), *u)).unzip();
    let peaks = row_peaks(&pos, &mat, 0, 0.05);
    let wavelength = 1e3 * peaks[0].wavelength;
    println!(
        "finger_quick: {per_frame:.2} s/frame; height swing {:.3} mm over the joint, {:.4} mm on the ends; \
         dominant wavelength {wavelength:.2} mm (kernels 6.00 mm)",
        1e3 * joint,
        1e3 * ends
    );
    assert!(joint > 0.2e-3, "wrinkles over the joint: {joint}");
    assert!(ends < 0.1 * joint, "none on the straight ends: {ends} vs {joint}");
    // Kernels bound a wavelength to a band, not a value (`coupling::kernels::KERNEL_SCALE`:
    // 0.9-1.4 lambda measured); the compression here peaks at the pivot and fades over 15 mm.
    assert!((0.9..=1.4).contains(&(wavelength / 6.0)), "wavelength {wavelength:.2} mm");
}

/// Issue 24 (LK14 5.4: "the angle of the joint would provide the interpolation parameter"):
/// wrinkle maps of the finger baked at joint angles 16 and 32 degrees, blended half and half,
/// against the map baked from the simulated frame at 24 degrees: the mean angle between their
/// normals, and the same for each key map alone.
#[test]
fn a_map_blended_by_joint_angle_matches_the_simulated_pose_better_than_either_key() {
    use skinsim_tools::bake::{bake, BakeRequest};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/finger_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let out = std::env::temp_dir().join(format!("skinsim_finger_bake_{}", std::process::id()));
    let req = BakeRequest {
        frames: Vec::new(),
        weights: Vec::new(),
        angles: vec![-16.0, -24.0, -32.0],
        size: 256,
        layer: Some("skin".into()),
        blends: Vec::new(),
        layout: Default::default(),
        ..Default::default()
    };
    let baked = bake(&built, &req, &out, None).unwrap().maps;
    assert_eq!(baked.iter().map(|b| b.frame).collect::<Vec<_>>(), vec![4, 6, 8], "the frames at those angles");
    let maps: Vec<image::RgbImage> = baked.iter().map(|b| image::open(&b.path).unwrap().to_rgb8()).collect();
    let every: Vec<(u32, u32)> = (0..256).flat_map(|y| (0..256).map(move |x| (x, y))).collect();
    let (with_blend, key_16, key_32) = blend_against_keys(&maps, &every);
    println!(
        "finger maps against the 24-degree frame: blend of 16 and 32 degrees {with_blend:.2} deg, \
         16-degree map {key_16:.2} deg, 32-degree map {key_32:.2} deg (mean angle between normals)"
    );
    assert!(with_blend < key_16.min(key_32), "blending helps");
    assert!(with_blend < BLEND_BOUND_DEGREES, "{with_blend}");
    let _ = std::fs::remove_dir_all(&out);
}

/// Maps baked at three angles against the middle one, over `pixels`: the mean angle between the
/// normals (degrees) of the half-and-half blend of the outer two, and of each outer one alone.
fn blend_against_keys(maps: &[image::RgbImage], pixels: &[(u32, u32)]) -> (f64, f64, f64) {
    use skinsim::mesh::wrinkle_map::{blend, decode};
    let mean_angle = |a: &image::RgbImage, b: &image::RgbImage| {
        let angle =
            |&(x, y): &(u32, u32)| decode(*a.get_pixel(x, y)).dot(decode(*b.get_pixel(x, y))).clamp(-1.0, 1.0).acos();
        (pixels.iter().map(angle).sum::<f64>() / pixels.len() as f64).to_degrees()
    };
    let blended = blend(&maps[0], &maps[2], 0.5);
    (mean_angle(&blended, &maps[1]), mean_angle(&maps[0], &maps[1]), mean_angle(&maps[2], &maps[1]))
}

/// The blend's bound: measured 2.03 degrees (the key maps alone: 5.30 and 5.86), with margin.
/// The maps hold world-space normals, so the bone's turn between the poses counts too.
const BLEND_BOUND_DEGREES: f64 = 3.0;

#[test]
fn angles_need_a_joint() {
    use skinsim_tools::bake::{frames_for, BakeRequest};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/lk14/fig3_3_e1_h1_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let req = |angles: Vec<f64>| BakeRequest {
        frames: Vec::new(),
        weights: Vec::new(),
        angles,
        size: 16,
        layer: None,
        blends: Vec::new(),
        layout: Default::default(),
        ..Default::default()
    };
    let e = frames_for(&built, &req(vec![30.0])).unwrap_err();
    assert!(e.contains("--angles needs a scene with a Joint driver"), "{e}");
    let e = frames_for(&built, &req(vec![f64::NAN])).unwrap_err();
    assert!(e.contains("--angles must be finite"), "{e}");
}

/// Issue 24, items 3 and 4: `hand_quick`, one hand-like body (an OBJ asset from `skinsim asset
/// hand`) shared by two LK14 knuckle patches and a KCK18 wrist sleeve. The fingers curl 40
/// degrees: each knuckle crease wrinkles over its joint at the kernel wavelength; the wrist
/// bends 20 degrees under the sleeve, whose anchors walk over the body.
#[test]
fn the_hand_carries_two_knuckle_patches_and_a_sleeve_on_one_body() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/hand_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    let clock = std::time::Instant::now();
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        assert_eq!(s.patches.len(), 3);
        assert!(s.patches.iter().all(|p| p.outcome.converged), "frame {frame}: {:?}", s.patches);
    }
    let per_frame = clock.elapsed().as_secs_f64() / built.scene.frames as f64;
    // One body layer in the world, not one per patch.
    let layers = sim.layers();
    assert_eq!(layers.iter().filter(|(_, l, _)| l == "hand").count(), 1, "{layers:?}");
    // Each knuckle: the skin's height over the body at the same material point, along the
    // body's normal (the skin is cut from the body's offset: same material coordinates).
    let (body_uv, body, body_faces) = sim.layer_surface("hand", "hand");
    let normals = vertex_normals(&body, &body_faces);
    let key = |u: DVec2| (u * 1e7).round().as_i64vec2().to_array();
    let on_body: std::collections::HashMap<[i64; 2], usize> =
        body_uv.iter().enumerate().map(|(i, u)| (key(*u), i)).collect();
    for knuckle in ["knuckle_a", "knuckle_b"] {
        let (uv, skin, _) = sim.layer_surface(knuckle, "skin");
        let height: Vec<f64> = uv
            .iter()
            .zip(&skin)
            .map(|(u, s)| {
                let b = on_body[&key(*u)];
                (*s - body[b]).dot(normals[b]) - 0.01875e-3
            })
            .collect();
        let swing = |keep: &dyn Fn(f64) -> bool| {
            let h: Vec<f64> = uv.iter().zip(&height).filter(|(u, _)| keep(u.x)).map(|(_, h)| *h).collect();
            h.iter().fold(f64::NEG_INFINITY, |m, x| m.max(*x)) - h.iter().fold(f64::INFINITY, |m, x| m.min(*x))
        };
        // The joint at x = 35 mm blends over 30 mm; the patch spans x = 10-60 mm.
        let joint = swing(&|x| (x - 0.035).abs() < 0.008);
        let ends = swing(&|x| (x - 0.035).abs() > 0.021);
        let (pos, mat): (Vec<DVec3>, Vec<DVec2>) = uv
            .iter()
            .zip(&height)
            .filter(|(u, _)| (u.x - 0.035).abs() < 0.015)
            .map(|(u, h)| (DVec3::new(0.0, 0.0, *h), *u))
            .unzip();
        let peaks = row_peaks(&pos, &mat, 0, 0.05);
        let wavelength = 1e3 * peaks[0].wavelength;
        println!(
            "hand_quick {knuckle}: {} skin vertices; height swing {:.3} mm over the joint, {:.3} mm at the \
             patch's ends; dominant wavelength {wavelength:.2} mm (kernels 6.00 mm)",
            uv.len(),
            1e3 * joint,
            1e3 * ends
        );
        assert!(joint > 0.2e-3, "{knuckle}: wrinkles over the joint: {joint}");
        assert!(ends < 0.5 * joint, "{knuckle}: fewer towards the straight parts: {ends} vs {joint}");
        assert!((0.9..=1.4).contains(&(wavelength / 6.0)), "{knuckle}: wavelength {wavelength:.2} mm");
    }
    // The sleeve's anchors walked over the bending wrist.
    let anchors = sim.anchors("sleeve");
    let walked = anchors.iter().filter(|(_, s)| s.walked > 0.0).count();
    println!("hand_quick: {per_frame:.2} s/frame; sleeve: {walked} of {} anchors walked", anchors.len());
    assert!(!anchors.is_empty() && walked > anchors.len() / 10, "{walked} of {}", anchors.len());
}

/// Issue 24, item 5: maps in the asset's own UV layout. On `hand_quick`, the knuckle skins are
/// baked into the hand's UV rectangle (their islands where the asset has them; issue 65: in the
/// asset's own vt, texels square) in the body's tangent space, at finger angles 16, 24 and 32
/// degrees, without padding or edge blending (8-bit, as first measured); the blend of 16 and 32
/// against the simulated 24-degree frame, over the pixels the knuckles cover, and each key
/// alone. Baking the sleeve too warns about its seam's flipped UV triangles, by face.
#[test]
fn asset_maps_in_tangent_space_blend_by_angle_and_name_bad_uv_triangles() {
    use skinsim::mesh::wrinkle_map::encode;
    use skinsim_tools::bake::{bake, BakeRequest, MapLayout};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/hand_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let out = std::env::temp_dir().join(format!("skinsim_hand_bake_{}", std::process::id()));
    let req = BakeRequest {
        angles: vec![16.0, 24.0, 32.0],
        size: 512,
        layout: MapLayout::Asset,
        padding: 0,
        edge_blend: 0.0,
        bits: 8,
        smooth: 0,
        ..Default::default()
    };
    let baked = bake(&built, &req, &out, None).unwrap();
    assert_eq!(baked.maps.iter().map(|b| b.frame).collect::<Vec<_>>(), vec![4, 6, 8], "the frames at those angles");
    assert!(baked.maps.iter().all(|m| m.patch == "hand"), "one map per body");
    // The sleeve is a closed tube cut from the arm: its seam's UV triangles run backwards.
    assert_eq!(baked.warnings.len(), 1, "{:?}", baked.warnings);
    assert!(baked.warnings[0].starts_with("sleeve/sleeve: 24 UV triangles are flipped"), "{:?}", baked.warnings);
    assert!(baked.warnings[0].contains("faces 62, 63, 126, 127"), "{:?}", baked.warnings);
    // The hand's vt rectangle (mm), 512 texels on its longer (v) side, square texels.
    let (_, lo, hi) = baked.rectangles[0];
    assert!((lo.x + 90.0).abs() < 1e-9 && hi.x >= 75.0 && (hi.y - 194.0691).abs() < 1e-3, "{lo} {hi}");
    let maps: Vec<image::RgbImage> = baked.maps.iter().map(|b| image::open(&b.path).unwrap().to_rgb8()).collect();
    let (w, h) = maps[0].dimensions();
    assert_eq!(h, 512);
    assert!(((hi.x - lo.x) / w as f64 - (hi.y - lo.y) / h as f64).abs() < 1e-12, "square texels: {w} x {h}");
    // Pixels of the knuckle islands (v above the arm's island) that a map draws on.
    let flat = encode(DVec3::Z);
    let v_of_row = |y: u32| hi.y - (y as f64 + 0.5) / h as f64 * (hi.y - lo.y);
    let covered: Vec<(u32, u32)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| v_of_row(y) > 100.0 && maps.iter().any(|m| *m.get_pixel(x, y) != flat))
        .collect();
    assert!(covered.len() > 1000, "{}", covered.len());
    let (with_blend, key_16, key_32) = blend_against_keys(&maps, &covered);
    println!(
        "hand asset maps (tangent space) against the 24-degree frame, over {} knuckle pixels: blend of 16 and 32 \
         degrees {with_blend:.2} deg, 16-degree map {key_16:.2} deg, 32-degree map {key_32:.2} deg",
        covered.len()
    );
    assert!(with_blend < key_16.min(key_32), "blending helps");
    assert!(with_blend < TANGENT_BLEND_BOUND_DEGREES, "{with_blend}");
    let _ = std::fs::remove_dir_all(&out);
}

/// The tangent-space blend's bound over the knuckle pixels: measured 2.27 degrees (the key maps
/// alone: 4.48 and 2.65), with margin. Tangent space takes the finger's turn out of the maps.
const TANGENT_BLEND_BOUND_DEGREES: f64 = 3.0;

/// Issue 24, item 4 (LK14 fig. 6-5): `curved_sheet_quick`, one shell on a compressed cylinder
/// strip, its thickness ramping from 0.25x to 1x around the arc. Geodesic eq. 3.1 kernels
/// (lambda ~ h^1/2) make the wrinkles shorter where the shell is thin: the wavelength along the
/// axis in the thinnest third against the thickest third.
#[test]
fn the_curved_sheet_wrinkles_shorter_where_it_is_thinner() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/curved_sheet_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none() && s.patches[0].outcome.converged, "frame {frame}: {:?}", s.patches[0]);
    }
    // Heights over the base along its normals (the skin is the base's offset: same vertices).
    let (_, base, faces) = sim.layer_surface("sheet", "base");
    let (uv, skin, _) = sim.layer_surface("sheet", "skin");
    let normals = vertex_normals(&base, &faces);
    let height: Vec<f64> = skin.iter().zip(&base).zip(&normals).map(|((s, b), n)| (*s - *b).dot(*n)).collect();
    let (lo, hi) = skinsim::mesh::bounds(&uv);
    let third = (hi.y - lo.y) / 3.0;
    let wavelength_in = |v0: f64, v1: f64| {
        let (pos, mat): (Vec<DVec3>, Vec<DVec2>) = uv
            .iter()
            .zip(&height)
            .filter(|(u, _)| (v0..=v1).contains(&u.y))
            .map(|(u, h)| (DVec3::new(0.0, 0.0, *h), *u))
            .unzip();
        1e3 * row_peaks(&pos, &mat, 0, 0.05)[0].wavelength
    };
    let (thin, thick) = (wavelength_in(lo.y, lo.y + third), wavelength_in(hi.y - third, hi.y));
    // Eq. 3.1: 4 (0.1 x 15)^1/2 (4 / 0.5)^1/6 = 6.93 mm at full thickness, times the square
    // root of the thirds' mean thickness factors, 0.375 and 0.875.
    let full = 4.0 * (0.1f64 * 15.0).sqrt() * 8.0f64.powf(1.0 / 6.0);
    let (kernel_thin, kernel_thick) = (full * 0.375f64.sqrt(), full * 0.875f64.sqrt());
    println!(
        "curved_sheet_quick: wavelength {thin:.2} mm on the thin third (kernels {kernel_thin:.2} mm), {thick:.2} mm \
         on the thick third (kernels {kernel_thick:.2} mm)"
    );
    assert!(thin < thick, "shorter where thinner: {thin} vs {thick}");
    // Kernels bound a wavelength to a band (`coupling::kernels::KERNEL_SCALE`: 0.9-1.4 lambda).
    for (measured, kernel) in [(thin, kernel_thin), (thick, kernel_thick)] {
        assert!((0.9..=1.4).contains(&(measured / kernel)), "{measured:.2} mm against the kernels' {kernel:.2} mm");
    }
}

/// The shipped assets are what `skinsim asset hand` writes (scenes/character/README.md gives the
/// commands): the quick one is rebuilt here and compared byte for byte.
#[test]
fn the_hand_asset_is_the_tools_output() {
    let out = std::env::temp_dir().join(format!("skinsim_hand_asset_{}", std::process::id()));
    let shape = skinsim::mesh::hand::HandShape { finger_cells: (40, 96), arm_cells: (32, 30) };
    let (vertices, faces) = skinsim_tools::asset::write_hand(&out, "hand_quick", shape).unwrap();
    assert_eq!((vertices, faces), (8752, 17280));
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/assets/hand_quick.obj");
    let same = std::fs::read(out.join("hand_quick.obj")).unwrap() == std::fs::read(shipped).unwrap();
    let _ = std::fs::remove_dir_all(&out);
    assert!(same, "scenes/character/assets/hand_quick.obj differs from the tool's output: regenerate it");
}

/// Issue 65: what a shader takes from an asset bake of `hand_quick` at 16 degrees. Against the
/// same bake without padding or edge blending: (1) the seam along each knuckle's edge, the
/// largest tilt of a drawn normal next to an undrawn pixel, falls from the skin's own to under
/// `EDGE_TILT_BOUND_DEGREES`; (2) no pixel within the padding (8) of a drawn one is left flat
/// (checked without the blend, which makes the edge itself flat);
/// (3) the 16-bit height map has the normal map's size, is 0 (grey 32768) away from the patches
/// and varies on them; (4) maps.json describes them.
#[test]
fn asset_maps_are_padded_faded_at_the_patch_edges_and_come_with_a_height_map() {
    use skinsim::mesh::map_buffer::{decode16, encode16};
    use skinsim_tools::bake::{bake, BakeRequest, MapLayout};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character/hand_quick.ron");
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let dir = std::env::temp_dir().join(format!("skinsim_hand_maps_{}", std::process::id()));
    let request = |padding: u32, edge_blend: f64, out: &str| {
        let req = BakeRequest {
            angles: vec![16.0],
            size: 512,
            layout: MapLayout::Asset,
            padding,
            edge_blend,
            ..Default::default()
        };
        let baked = bake(&built, &req, &dir.join(out), None).unwrap();
        let img = image::open(&baked.maps[0].path).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgb16, "16-bit by default");
        img.to_rgb16()
    };
    let before = request(0, 0.0, "before");
    let padded_only = request(8, 0.0, "padded");
    let after = request(8, 2e-3, "after");
    let (w, h) = before.dimensions();
    let flat = encode16(DVec3::Z);
    let drawn = |x: i64, y: i64| {
        (0..w as i64).contains(&x) && (0..h as i64).contains(&y) && *before.get_pixel(x as u32, y as u32) != flat
    };
    let tilt = |img: &image::ImageBuffer<image::Rgb<u16>, Vec<u16>>, x: u32, y: u32| {
        decode16(*img.get_pixel(x, y)).angle_between(DVec3::Z).to_degrees()
    };
    let (mut seam_before, mut seam_after, mut padded, mut left_flat) = (0.0f64, 0.0f64, 0, 0);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let ring = |r: i64| (-r..=r).any(|dy| (-r..=r).any(|dx| drawn(x + dx, y + dy)));
            // (the knuckles' edges: v above the arm's island; the sleeve's seam is a UV border
            // inside the skin, where the map is discontinuous by the asset's layout)
            let knuckle = (y as f64 + 0.5) / (h as f64) < 0.45;
            let edge = [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|(dx, dy)| !drawn(x + dx, y + dy));
            if knuckle && drawn(x, y) && edge {
                seam_before = seam_before.max(tilt(&before, x as u32, y as u32));
                seam_after = seam_after.max(tilt(&after, x as u32, y as u32));
            }
            if !drawn(x, y) && ring(8) {
                padded += 1;
                left_flat += (*padded_only.get_pixel(x as u32, y as u32) == flat) as usize;
            }
        }
    }
    println!(
        "hand_quick asset map at 16 degrees ({w} x {h}): the largest tilt of a drawn normal at a patch's edge \
         {seam_before:.1} deg unblended, {seam_after:.2} deg blended over 2 mm; {padded} padding pixels, \
         {left_flat} left flat"
    );
    assert!(seam_before > 5.0, "the unblended edge shows the skin's tilt: {seam_before}");
    assert!(seam_after < EDGE_TILT_BOUND_DEGREES, "{seam_after}");
    assert!(padded > 1000 && left_flat == 0, "{padded} {left_flat}");
    let heights = image::open(dir.join("after/hand_height_00004.png")).unwrap();
    assert_eq!((heights.width(), heights.height(), heights.color()), (w, h, image::ColorType::L16));
    let heights = heights.to_luma16();
    assert_eq!(heights.get_pixel(0, h - 1).0[0], 32768, "0 away from the patches");
    let on: Vec<u16> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| drawn(x as i64, y as i64))
        .map(|(x, y)| heights.get_pixel(x, y).0[0])
        .collect();
    let (lo, hi) = (on.iter().min().unwrap(), on.iter().max().unwrap());
    assert!(hi - lo > 200, "the wrinkles show in the heights: {lo}..{hi}");
    let sidecar: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("after/maps.json")).unwrap()).unwrap();
    assert_eq!(sidecar["height_range_m"].as_f64(), Some(5e-3));
    assert_eq!(sidecar["bodies"][0]["body"], "hand");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The largest tilt of a drawn normal at a knuckle's edge once blended over 2 mm (measured in
/// the test above; unblended it is the skin's own).
const EDGE_TILT_BOUND_DEGREES: f64 = 3.0;
