//! Issue 64: barrier contact. Skin that folds onto itself never passes through itself and never
//! comes closer than the contact thickness, checked on every frame by references that share no
//! code with the contact module: Shewchuk's exact orientation predicates for crossing
//! triangles (`mesh::crossing`) and a clamped-projection distance written here. The same
//! scene without contact does cross, so the test can fail.

mod common;

use common::*;
use glam::DVec3;
use skinsim::mesh::crossing::crossing_pairs;
use skinsim::scene::load_str;
use skinsim_systems::{FrameStats, Simulation};

/// Squared distance from p to the segment a-b (clamped projection).
fn point_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let e = b - a;
    let t = if e.length_squared() > 0.0 { ((p - a).dot(e) / e.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + t * e)).length_squared()
}

/// Squared distance from p to the triangle: its plane where the foot is inside, else its edges.
fn point_triangle(p: DVec3, t: [DVec3; 3]) -> f64 {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let foot = p - n * ((p - t[0]).dot(n) / n.length_squared());
    let inside = (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(foot - t[k]).dot(n) >= 0.0);
    let edges = (0..3).map(|k| point_segment(p, t[k], t[(k + 1) % 3])).fold(f64::INFINITY, f64::min);
    if inside {
        edges.min((p - foot).length_squared())
    } else {
        edges
    }
}

/// Squared distance between segments a and b: the interior closest points where both fall
/// inside, else the endpoints against the other segment.
fn segment_segment(a: [DVec3; 2], b: [DVec3; 2]) -> f64 {
    let (u, v, w) = (a[1] - a[0], b[1] - b[0], a[0] - b[0]);
    let (uu, uv, vv, uw, vw) = (u.dot(u), u.dot(v), v.dot(v), u.dot(w), v.dot(w));
    let den = uu * vv - uv * uv;
    let mut best = point_segment(a[0], b[0], b[1])
        .min(point_segment(a[1], b[0], b[1]))
        .min(point_segment(b[0], a[0], a[1]))
        .min(point_segment(b[1], a[0], a[1]));
    if den > 1e-14 * uu * vv {
        let (s, t) = ((uv * vw - vv * uw) / den, (uu * vw - uv * uw) / den);
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            best = best.min(((a[0] + s * u) - (b[0] + t * v)).length_squared());
        }
    }
    best
}

fn edges_of(faces: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> =
        faces.iter().flat_map(|f| (0..3).map(move |k| [f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3])])).collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// The smallest distance between a vertex and a triangle, or two edges, of one surface that
/// are not neighbours at rest (their rest distance is above `apart`): all pairs, culled only by
/// their bounding boxes' distance, up to CAP.
fn closest_approach(x: &[DVec3], rest: &[DVec3], faces: &[[u32; 3]], apart: f64) -> f64 {
    // (`x` and `rest` must number the vertices alike, as `layer_mesh` and the mesh's rest do:
    // `layer_surface` numbers them in first use, and the rule "apart at rest" then reads other
    // vertices' rest positions. The faces' longest edges at rest and now agree within 2x in
    // the median; numbered apart, they were 10x on the quick creature.)
    let longest = |y: &[DVec3], f: &[u32; 3]| {
        (0..3).map(|k| y[f[k] as usize].distance(y[f[(k + 1) % 3] as usize])).fold(0.0, f64::max)
    };
    let mut ratios: Vec<f64> = faces.iter().map(|f| longest(rest, f) / longest(x, f)).collect();
    ratios.sort_by(f64::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(1.0);
    assert!((0.5..2.0).contains(&median), "positions and rest numbered alike: median edge ratio {median}");
    let edges = edges_of(faces);
    let at = |y: &[DVec3], f: &[u32; 3]| f.map(|v| y[v as usize]);
    let seg = |y: &[DVec3], e: &[u32; 2]| e.map(|v| y[v as usize]);
    use rayon::prelude::*;
    // (pairs whose bounding boxes lie over CAP apart are not measured: a box's distance is at
    // most its contents')
    let boxes = |ps: &[DVec3]| {
        (ps.iter().fold(DVec3::INFINITY, |a, b| a.min(*b)), ps.iter().fold(DVec3::NEG_INFINITY, |a, b| a.max(*b)))
    };
    let close = |a: (DVec3, DVec3), b: (DVec3, DVec3)| (a.0 - b.1).max(b.0 - a.1).max(DVec3::ZERO).length() <= CAP;
    let face_box: Vec<_> = faces.iter().map(|f| boxes(&at(x, f))).collect();
    let edge_box: Vec<_> = edges.iter().map(|e| boxes(&seg(x, e))).collect();
    let points = x.par_iter().enumerate().map(|(v, p)| {
        let far = |(f, b): &(&[u32; 3], &(DVec3, DVec3))| {
            !f.contains(&(v as u32)) && close((*p, *p), **b) && point_triangle(rest[v], at(rest, f)).sqrt() > apart
        };
        let measured = faces.iter().zip(&face_box).filter(far);
        measured.map(|(f, _)| point_triangle(*p, at(x, f)).sqrt()).fold(CAP, f64::min)
    });
    let segments = edges.par_iter().enumerate().map(|(i, a)| {
        let far = |(b, bb): &(&[u32; 2], &(DVec3, DVec3))| {
            !b.iter().any(|v| a.contains(v))
                && close(edge_box[i], **bb)
                && segment_segment(seg(rest, a), seg(rest, b)).sqrt() > apart
        };
        let measured = edges[i + 1..].iter().zip(&edge_box[i + 1..]).filter(far);
        measured.map(|(b, _)| segment_segment(seg(x, a), seg(x, b)).sqrt()).fold(CAP, f64::min)
    });
    points.chain(segments).reduce(|| CAP, f64::min)
}

/// The distance beyond which `closest_approach` does not measure (it returns CAP): above every
/// thickness the tests assert (m).
const CAP: f64 = 5e-3;

/// The smallest distance between two surfaces: vertices against triangles both ways, and
/// edges against edges.
fn closest_between(a: (&[DVec3], &[[u32; 3]]), b: (&[DVec3], &[[u32; 3]])) -> f64 {
    let one_way = |(xa, _): (&[DVec3], &[[u32; 3]]), (xb, fb): (&[DVec3], &[[u32; 3]])| {
        xa.iter()
            .flat_map(|p| fb.iter().map(move |f| point_triangle(*p, f.map(|v| xb[v as usize]))))
            .fold(f64::INFINITY, f64::min)
    };
    let (ea, eb) = (edges_of(a.1), edges_of(b.1));
    let edges = ea
        .iter()
        .flat_map(|e| eb.iter().map(move |g| segment_segment(e.map(|v| a.0[v as usize]), g.map(|v| b.0[v as usize]))))
        .fold(f64::INFINITY, f64::min);
    one_way(a, b).min(one_way(b, a)).min(edges).sqrt()
}

/// The layers' surfaces as one mesh (for the crossing test between them).
fn merged(parts: &[(Vec<DVec3>, Vec<[u32; 3]>)]) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let (mut x, mut faces) = (Vec::new(), Vec::new());
    for (px, pf) in parts {
        let base = x.len() as u32;
        x.extend_from_slice(px);
        faces.extend(pf.iter().map(|f| f.map(|v| v + base)));
    }
    (x, faces)
}

/// The frames of the scene whose layer crosses itself.
fn frames_crossing(scene: &skinsim::scene::BuiltScene, patch: &str, layer: &str) -> usize {
    let mut sim = Simulation::new(scene);
    (0..scene.scene.frames)
        .filter(|_| {
            sim.step();
            let (_, x, faces) = sim.layer_surface(patch, layer);
            !crossing_pairs(&faces, &x).is_empty()
        })
        .count()
}

/// Runs the scene and measures each frame with `measure` (the simulation after the step, and
/// the step's stats).
/// Asserts every frame converges.
fn every_frame<T>(
    scene: &skinsim::scene::BuiltScene,
    mut measure: impl FnMut(&mut Simulation, &FrameStats) -> T,
) -> Vec<T> {
    let mut sim = Simulation::new(scene);
    let mut out = Vec::new();
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        assert!(s.patches.iter().all(|p| p.outcome.converged), "frame {frame} converges");
        out.push(measure(&mut sim, &s));
    }
    out
}

/// A strip folded onto itself (`scenes/examples/fold_strip.ron`, its upper ply's end held and
/// carried down through the lower ply): with contact, no frame has a crossing or two plies
/// closer than the 0.3 mm thickness; without, the plies cross.
#[test]
fn a_strip_folded_onto_itself_never_passes_through() {
    let rel = "examples/fold_strip.ron";
    let thickness = 0.3e-3;
    // (pairs within 1.5 mm at rest are neighbours on the strip, 1 mm cells: not its plies)
    let apart = 1.5e-3;
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, x, faces) = sim.layer_mesh("strip", "strip");
        (x, faces)
    };
    let rest_of =
        |scene: &skinsim::scene::BuiltScene| -> Vec<DVec3> { scene.patches[0].layers[0].mesh.rest().to_vec() };
    let with_scene = load(rel);
    let rest = rest_of(&with_scene);
    for (frame, (x, faces)) in every_frame(&with_scene, measure).iter().enumerate() {
        assert_eq!(crossing_pairs(faces, x).len(), 0, "frame {}: crossing faces", frame + 1);
        let closest = closest_approach(x, &rest, faces, apart);
        assert!(closest > thickness, "frame {}: {closest} m is below the thickness", frame + 1);
    }
    let without = variant(rel, &[("contact: Some((thickness: 0.3, d_hat: 0.15)),", "")]);
    let crossed = every_frame(&without, measure).iter().filter(|(x, f)| !crossing_pairs(f, x).is_empty()).count();
    assert!(crossed > 0, "without contact the plies pass through each other");
}

/// A sheet pressed onto a sphere (`scenes/examples/press_sphere.ron`): with contact, no sheet
/// face crosses a sphere face and the sheet stays more than half its 0.3 mm thickness from the
/// sphere at every frame; without, the sphere passes through the sheet.
#[test]
fn a_sheet_pressed_onto_a_sphere_drapes_over_it() {
    let rel = "examples/press_sphere.ron";
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, xs, fs) = sim.layer_surface("sheet", "sheet");
        let (_, xb, fb) = sim.layer_surface("sheet", "sphere");
        let (x, faces) = merged(&[(xs.clone(), fs.clone()), (xb.clone(), fb.clone())]);
        (crossing_pairs(&faces, &x).len(), closest_between((&xs, &fs), (&xb, &fb)))
    };
    for (frame, &(crossing, closest)) in every_frame(&load(rel), measure).iter().enumerate() {
        assert_eq!(crossing, 0, "frame {}: the sheet crosses the sphere", frame + 1);
        assert!(closest > 0.15e-3, "frame {}: {closest} m from the sphere", frame + 1);
    }
    let without = variant(rel, &[("contact: Some((thickness: 0.3, d_hat: 0.15)),", "")]);
    let crossed = every_frame(&without, measure).iter().filter(|m| m.0 > 0).count();
    assert!(crossed > 0, "without contact the sphere passes through the sheet");
}

/// Contact on a remeshed layer (CCD bounds every step, in Newton and in Settle): the sheet
/// pressed onto the sphere, refined where it drapes over it. Near contact the remesh keeps the
/// surface's shape (splits on the straight edge, no flip or collapse), and the Settle moves the
/// skin from where the last solve left it under the collision bound. Every frame converges, no
/// sheet face crosses the sphere or comes within half the thickness of it, and the sheet is
/// refined (1,279 vertices at the start; remeshed at frames 4-6 of the first 6, where the
/// sphere has risen 2.25 mm into it).
#[test]
fn a_remeshed_sheet_pressed_onto_a_sphere_never_passes_through() {
    let remesh = "bending: Some((model: Tan)),\n                      remesh: Some((size_min: 0.3, size_max: 1.5, \
                  refine_angle: 0.1, refine_compression: 0.02))),";
    let scene = variant(
        "examples/press_sphere.ron",
        &[("bending: Some((model: Tan))),", remesh), ("frames: 8,", "frames: 6,")],
    );
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, xs, fs) = sim.layer_surface("sheet", "sheet");
        let (_, xb, fb) = sim.layer_surface("sheet", "sphere");
        let (x, faces) = merged(&[(xs.clone(), fs.clone()), (xb.clone(), fb.clone())]);
        (crossing_pairs(&faces, &x).len(), closest_between((&xs, &fs), (&xb, &fb)), xs.len())
    };
    let frames = every_frame(&scene, measure);
    for (frame, &(crossing, closest, _)) in frames.iter().enumerate() {
        assert_eq!(crossing, 0, "frame {}: the sheet crosses the sphere", frame + 1);
        assert!(closest > 0.15e-3, "frame {}: {closest} m from the sphere", frame + 1);
    }
    let vertices: Vec<usize> = frames.iter().map(|f| f.2).collect();
    assert!(vertices.last() > vertices.first(), "the sheet is refined: {vertices:?}");
}

/// Friction (`scenes/examples/grip_sphere.ron`): the sheet pressed onto the sphere grips it
/// (mu = 1) as it turns 2 degrees about its centre, so the sheet over the sphere's top is
/// carried along with it (0.21 mm) where static friction holds; frictionless, the sphere turns
/// under the sheet (its shape unchanged) and leaves it in place. Every frame converges and
/// neither run crosses the sphere.
#[test]
fn skin_grips_where_static_friction_holds() {
    let rel = "examples/grip_sphere.ron";
    let top_moves = 6e-3 * 2f64.to_radians().sin();
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, xs, fs) = sim.layer_surface("sheet", "sheet");
        let (_, xb, fb) = sim.layer_surface("sheet", "sphere");
        let (x, faces) = merged(&[(xs.clone(), fs.clone()), (xb, fb)]);
        assert!(crossing_pairs(&faces, &x).is_empty(), "the sheet crosses the sphere");
        xs
    };
    // How far the sheet's vertex over the sphere's top moves while the sphere turns (frames
    // 8-16), over how far the top moves.
    let carried = |scene: &skinsim::scene::BuiltScene| {
        let x = every_frame(scene, measure);
        let (pressed, turned) = (&x[7], &x[15]);
        let top = (0..pressed.len())
            .min_by(|&a, &b| {
                let d = |p: DVec3| (p.x - 10e-3).powi(2) + (p.y - 10e-3).powi(2);
                d(pressed[a]).total_cmp(&d(pressed[b]))
            })
            .unwrap();
        (turned[top].x - pressed[top].x) / top_moves
    };
    let gripped = carried(&load(rel));
    assert!(gripped > 0.9, "with friction the sheet's top moves {gripped} of the sphere's top");
    let frictionless = carried(&variant(rel, &[("friction: 1.0", "friction: 0.0")]));
    assert!(frictionless.abs() < 0.1, "frictionless, the sheet's top moves {frictionless} of the sphere's top");
}

/// Contact between two patches (`scenes/examples/two_strips.ron`: a strip whose held ends are
/// carried down across another, each its own patch, each naming the other in `contact.with`):
/// solved in turn, no frame ends with the strips crossing or closer than the 0.3 mm thickness;
/// without `with` the upper strip passes through the lower one.
#[test]
fn two_patches_never_pass_through_each_other() {
    let rel = "examples/two_strips.ron";
    // Crossing faces, the closest approach, and the upper strip's height above the lower one
    // where they cross (mean heights of their vertices within x in [0, 4] and y in [8, 12] mm).
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, xl, fl) = sim.layer_surface("lower", "strip");
        let (_, xu, fu) = sim.layer_surface("upper", "strip");
        let (x, faces) = merged(&[(xl.clone(), fl.clone()), (xu.clone(), fu.clone())]);
        let height = |x: &[DVec3]| {
            let z: Vec<f64> = x
                .iter()
                .filter(|p| (-1e-6..=4e-3 + 1e-6).contains(&p.x) && (8e-3 - 1e-6..=12e-3 + 1e-6).contains(&p.y))
                .map(|p| p.z)
                .collect();
            z.iter().sum::<f64>() / z.len() as f64
        };
        (crossing_pairs(&faces, &x).len(), closest_between((&xl, &fl), (&xu, &fu)), height(&xu) - height(&xl))
    };
    for (frame, &(crossing, closest, above)) in every_frame(&load(rel), measure).iter().enumerate() {
        assert_eq!(crossing, 0, "frame {}: the strips cross", frame + 1);
        assert!(closest > 0.3e-3 && above > 0.3e-3, "frame {}: {closest} m apart, {above} m above", frame + 1);
    }
    let without = variant(rel, &[(", with: [\"upper\"]", ""), (", with: [\"lower\"]", "")]);
    let last = *every_frame(&without, measure).last().unwrap();
    assert!(last.2 < 0.0, "without contact between the patches the upper strip passes below: {} m", last.2);
}

/// Contact against a scene body (`scenes/examples/press_body.ron`: the sphere of press_sphere.ron
/// as a body of the scene, named in the sheet's `contact.with`): no frame has the sheet crossing
/// the sphere or nearer than half its 0.3 mm thickness; without `with`, the sphere passes
/// through.
#[test]
fn a_sheet_touches_a_scene_body_it_names() {
    let rel = "examples/press_body.ron";
    let measure = |sim: &mut Simulation, _: &FrameStats| {
        let (_, xs, fs) = sim.layer_surface("sheet", "sheet");
        let (_, xb, fb) = sim.layer_surface("ball", "ball");
        let (x, faces) = merged(&[(xs.clone(), fs.clone()), (xb.clone(), fb.clone())]);
        (crossing_pairs(&faces, &x).len(), closest_between((&xs, &fs), (&xb, &fb)))
    };
    for (frame, &(crossing, closest)) in every_frame(&load(rel), measure).iter().enumerate() {
        assert_eq!(crossing, 0, "frame {}: the sheet crosses the body", frame + 1);
        assert!(closest > 0.15e-3, "frame {}: {closest} m from the body", frame + 1);
    }
    let without = variant(rel, &[(", with: [\"ball\"]", "")]);
    let crossed = every_frame(&without, measure).iter().filter(|m| m.0 > 0).count();
    assert!(crossed > 0, "without `with` the body passes through the sheet");
}

/// Determinism: the folded strip (contact active from frame 5) gives the same bits with 1 and
/// 2 threads.
#[test]
fn contact_gives_the_same_bits_whatever_the_thread_count() {
    let scene = variant("examples/fold_strip.ron", &[("frames: 8,", "frames: 6,")]);
    let bits: Vec<Vec<[u64; 3]>> = [1, 2]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| {
                let mut sim = Simulation::new(&scene);
                let pairs = every_frame_of(&mut sim, &scene);
                assert!(pairs > 0, "contact is active");
                sim.layer_surface("strip", "strip").1.iter().map(|p| p.to_array().map(f64::to_bits)).collect()
            })
        })
        .collect();
    assert!(bits[0] == bits[1], "1 and 2 threads differ");
}

/// Steps every frame; returns the most active pairs in a frame.
fn every_frame_of(sim: &mut Simulation, scene: &skinsim::scene::BuiltScene) -> usize {
    let mut most = 0;
    for _ in 0..scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "{:?}", sim.failure());
        most = most.max(s.patches.iter().filter_map(|p| p.outcome.contact).map(|c| c.active_pairs).max().unwrap_or(0));
    }
    most
}

/// A small patch with contact, for the refusals below.
const CONTACT: &str = r#"Scene(
    name: "contact",
    frames: 1,
    patches: [
        Patch(
            name: "p",
            layers: [
                Layer(name: "film", kind: Shell, mesh: Grid(size: (4.0, 2.0), cells: (4, 2)),
                      material: (young: 1.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
            ],
            drivers: [Pin(layer: "film", select: Sides([XMin]))],
            contact: Some((thickness: 0.1, d_hat: 0.05)),
        ),
    ],
)"#;

fn refused(text: &str) -> skinsim::scene::SceneError {
    load_str(text, std::path::Path::new("scene.ron")).expect_err("should be refused")
}

#[test]
fn bad_contact_input_is_refused_naming_the_field() {
    load_str(CONTACT, std::path::Path::new("scene.ron")).unwrap();
    let e = refused(&CONTACT.replace("thickness: 0.1, d_hat", "thickness: 0.0, d_hat"));
    mentions(&e, &["patches[0] (\"p\").contact.thickness", "positive"]);
    let e = refused(&CONTACT.replace("d_hat: 0.05", "d_hat: -1.0"));
    mentions(&e, &["patches[0] (\"p\").contact.d_hat", "positive"]);
    // (beyond the patch's 4.5 mm extent: every pair would touch)
    let e = refused(&CONTACT.replace("d_hat: 0.05", "d_hat: 1e300"));
    mentions(&e, &["patches[0] (\"p\").contact.d_hat", "extent"]);
    let e = refused(&CONTACT.replace("thickness: 0.1, d_hat", "thickness: 5.0, d_hat"));
    mentions(&e, &["patches[0] (\"p\").contact.thickness", "extent"]);
    let e = refused(&CONTACT.replace("d_hat: 0.05)", "d_hat: 0.05, friction: -0.5)"));
    mentions(&e, &["patches[0] (\"p\").contact.friction", "coefficient"]);
    let e = refused(&CONTACT.replace("d_hat: 0.05)", "d_hat: 0.05, friction: 0.5, sticking: 0.0)"));
    mentions(&e, &["patches[0] (\"p\").contact.sticking", "positive"]);
    let e = refused(
        &CONTACT
            .replace("frames: 1,", "frames: 1, frame_time: 0.01,")
            .replace("name: \"p\",", "name: \"p\", solver: (mode: ImplicitEuler),"),
    );
    mentions(&e, &["patches[0] (\"p\").contact", "dynamics"]);
    let e = refused(&CONTACT.replace("name: \"p\",", "name: \"p\", solver: (globalization: TrustRegion),"));
    mentions(&e, &["patches[0] (\"p\").contact", "TrustRegion"]);
    let remeshed = "bending: (model: Tan),\n                      remesh: Some((size_min: 0.25, size_max: 2.0, refine_angle: 0.3, \
                     refine_compression: 0.2, local_solve: true))),";
    let e = refused(&CONTACT.replace("bending: (model: Tan)),", remeshed));
    mentions(&e, &["patches[0] (\"p\").contact", "local_solve"]);
    load_str(
        &CONTACT.replace("bending: (model: Tan)),", &remeshed.replace(", local_solve: true", "")),
        "s.ron".as_ref(),
    )
    .expect("contact on a remeshed layer");
    let e = refused(&CONTACT.replace("contact: Some((thickness: 0.1, d_hat: 0.05)),", "contact: Some((d_hat: 0.05)),"));
    mentions(&e, &["thickness"]);
    // A start closer than the thickness: a body 0.02 under a film whose barrier keeps 0.05.
    let close = CONTACT.replace(
        "layers: [\n",
        "layers: [\n                Layer(name: \"floor\", kind: Kinematic, mesh: Grid(size: (4.0, 2.0), cells: (4, 2), z: -0.02)),\n",
    );
    // It is pushed out, with a warning: the film lifted to the barrier's offset over the floor,
    // and it runs.
    let scene = load_str(&close, std::path::Path::new("scene.ron")).expect("pushed out");
    let warned = |n: &String| n.contains("patches[0] (\"p\").contact") && n.contains("pushed out");
    assert!(scene.notes.iter().any(warned), "{:?}", scene.notes);
    let lowest = scene.patches[0].layers[1].mesh.rest().iter().map(|v| v.z).fold(f64::INFINITY, f64::min);
    // (millimetres: the offset 0.05 over a floor at -0.02, within 1 %)
    assert!(lowest > 0.03e-3 && lowest < (0.05 * 1.01 - 0.02) * 1e-3, "{lowest} m");
    let mut sim = Simulation::new(&scene);
    sim.step();
    assert!(sim.failure().is_none(), "{:?}", sim.failure());
    // Touching it (no separation to push along) is refused, naming the layers.
    let e = refused(&close.replace("z: -0.02", "z: 0.0"));
    mentions(&e, &["patches[0] (\"p\").contact", "layer \"floor\""]);
    // `with`: a body or another patch that exists and has contact of its own.
    let e = refused(&CONTACT.replace("d_hat: 0.05)", "d_hat: 0.05, with: [\"nobody\"])"));
    mentions(&e, &["patches[0] (\"p\").contact.with[0]", "no body or patch is named \"nobody\""]);
    let e = refused(&CONTACT.replace("d_hat: 0.05)", "d_hat: 0.05, with: [\"p\"])"));
    mentions(&e, &["patches[0] (\"p\").contact.with[0]", "itself"]);
    // (a second patch, "q", without contact)
    let q = r#"Patch(
            name: "q",
            layers: [
                Layer(name: "film", kind: Shell, mesh: Grid(size: (4.0, 2.0), cells: (4, 2), z: 1.0),
                      material: (young: 1.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
            ],
            drivers: [Pin(layer: "film", select: Sides([XMin]))],
        ),
    ],
)"#;
    let two = CONTACT.replace("d_hat: 0.05)", "d_hat: 0.05, with: [\"q\"])").replace("    ],\n)", q);
    assert!(two.contains("name: \"q\""));
    let e = refused(&two);
    mentions(&e, &["patches[0] (\"p\").contact.with[0]", "no contact of its own"]);
}

/// A start state whose shells already cross is refused, naming both faces and their layers.
#[test]
fn a_start_state_that_crosses_is_refused() {
    let dir = scratch_dir("contact");
    // Two unit squares through each other: one flat at z = 0, one standing across it.
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    let standing = "v 0.5 -0.2 -0.5\nv 0.5 1.2 -0.5\nv 0.5 1.2 0.5\nv 0.5 -0.2 0.5\nvt 0 0\nvt 1.4 0\nvt 1.4 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    std::fs::write(dir.join("flat.obj"), obj).unwrap();
    std::fs::write(dir.join("standing.obj"), standing).unwrap();
    let text = CONTACT.replace(
        r#"Layer(name: "film", kind: Shell, mesh: Grid(size: (4.0, 2.0), cells: (4, 2)),"#,
        r#"Layer(name: "standing", kind: Kinematic, mesh: Obj(path: "standing.obj")),
                Layer(name: "film", kind: Shell, mesh: Obj(path: "flat.obj"),"#,
    );
    let e = load_str(&text, &dir.join("scene.ron")).expect_err("crossing start");
    mentions(&e, &["patches[0] (\"p\").contact", "already crosses", "layer \"film\"", "layer \"standing\""]);
}

/// The KCK18 creature with contact on its skin (`scenes/kck18/creature_contact_quick.ron`), on
/// a kinematic body that intersects itself at the bent waist: every frame converges, the skin's
/// folds there touch (active pairs), and no frame has a crossing or two parts of the skin
/// closer than its 1 mm thickness. The same scene
/// without contact (`creature_quick.ron`) does cross.
#[test]
fn the_creature_skin_folds_without_passing_through() {
    let scene = load("kck18/creature_contact_quick.ron");
    let rest = scene.patches[0].layers[1].mesh.rest().to_vec();
    let (mut most, mut body_crossed) = (0, 0);
    let mut sim = Simulation::new(&scene);
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        let c = s.patches[0].outcome.contact.expect("a contact report");
        most = most.max(c.active_pairs);
        assert!(s.patches[0].outcome.converged && c.min_distance_ratio > 1.0, "frame {frame}: {c:?}");
        let (_, x, faces) = sim.layer_mesh("creature", "skin");
        assert!(crossing_pairs(&faces, &x).is_empty(), "frame {frame}: crossing faces");
        let (_, xb, fb) = sim.layer_surface("creature", "body");
        body_crossed += usize::from(!crossing_pairs(&fb, &xb).is_empty());
        // (neighbours within 1.5 mm at rest are excluded; the mesh's edges are about 10 mm)
        let closest = closest_approach(&x, &rest, &faces, 1.5e-3);
        assert!(closest > 1e-3, "frame {frame}: {closest} m");
    }
    assert!(most > 100, "the folds touch: {most} active pairs at most");
    // The body the skin is anchored to folds through itself at the bent waist (its surface
    // crosses itself in frames 2-8): the skin on it still neither crosses nor fails a frame.
    assert!(body_crossed >= 5, "the body crosses itself in {body_crossed} frames");
    let without = load("kck18/creature_quick.ron");
    assert!(frames_crossing(&without, "creature", "skin") > 0, "without contact the skin passes through itself");
}

/// Scope 3 on an LK14 skin (`scenes/character/finger_fold_quick.ron`): a finger bent 105
/// degrees over a joint 10 mm wide, so that its bone's surface folds through itself (crossing
/// faces in at least 4 of the 7 frames), as linear blend skinning does at a real joint. Contact
/// releases the kernels whose body point comes within a third of a kernel's radius of another
/// part of the bone, or whose skin touches (`src/solve/release.rs`): every frame converges,
/// some kernels are released, and the skin neither crosses itself nor comes closer to itself
/// than its 37.5 um thickness. Without contact the skin crosses itself.
#[test]
fn lk14_skin_over_a_joint_that_folds_through_itself_never_crosses() {
    let rel = "character/finger_fold_quick.ron";
    let scene = load(rel);
    let rest = scene.patches[0].layers[1].mesh.rest().to_vec();
    let (mut body_crossed, mut released) = (0, 0);
    let mut sim = Simulation::new(&scene);
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        let c = s.patches[0].outcome.contact.expect("a contact report");
        assert!(s.patches[0].outcome.converged, "frame {frame}: {} iterations", s.patches[0].outcome.iterations);
        released = released.max(c.released_kernels);
        let (_, x, faces) = sim.layer_mesh("finger", "skin");
        assert!(crossing_pairs(&faces, &x).is_empty(), "frame {frame}: the skin crosses itself");
        let (_, xb, fb) = sim.layer_surface("finger", "bone");
        body_crossed += usize::from(!crossing_pairs(&fb, &xb).is_empty());
        // (neighbours within 0.2 mm at rest are excluded: the cells are 0.75 mm)
        let closest = closest_approach(&x, &rest, &faces, 0.2e-3);
        assert!(closest > 0.0375e-3, "frame {frame}: {closest} m");
    }
    assert!(body_crossed >= 4, "the bone crosses itself in {body_crossed} frames");
    assert!(released > 0, "no kernel was released");
    let without = variant(rel, &[("contact: Some((thickness: 0.0375)),", "")]);
    assert!(frames_crossing(&without, "finger", "skin") > 0, "without contact the skin passes through itself");
}

/// The LK14 pinch squeezed until its folds lie over each other
/// (`scenes/lk14/pinch_folded_quick.ron`: the base drawn in between two fingers by 1.6 times
/// the distance, so that its middle folds over its sides). With contact every frame converges;
/// the dermis and epidermis cross neither themselves nor each other nor (the epidermis) the
/// base, and no two skin surfaces come closer than the 0.1 mm thickness; kernels are released
/// where the base folds. Without contact the skin crosses itself or its other layer.
#[test]
fn a_pinch_folded_over_itself_never_passes_through() {
    let rel = "lk14/pinch_folded_quick.ron";
    let scene = load(rel);
    let skins = |sim: &mut Simulation| ["dermis", "epidermis"].map(|l| sim.layer_surface("skin", l));
    let crossing = |sim: &mut Simulation| {
        let [(_, xd, fd), (_, xe, fe)] = skins(sim);
        let (x, f) = merged(&[(xd, fd), (xe, fe)]);
        crossing_pairs(&f, &x).len()
    };
    let rest = {
        let [(_, xd, fd), (_, xe, fe)] = skins(&mut Simulation::new(&scene));
        merged(&[(xd, fd), (xe, fe)]).0
    };
    let mut released = 0;
    let mut sim = Simulation::new(&scene);
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        assert!(s.patches[0].outcome.converged, "frame {frame}: {} iterations", s.patches[0].outcome.iterations);
        released = released.max(s.patches[0].outcome.contact.expect("a contact report").released_kernels);
        assert_eq!(crossing(&mut sim), 0, "frame {frame}: the skin crosses");
        let [(_, xd, fd), (_, xe, fe)] = skins(&mut sim);
        let (x, faces) = merged(&[(xd, fd), (xe.clone(), fe.clone())]);
        // (neighbours on one layer within 0.3 mm at rest, twice the barrier's reach, never pair)
        let closest = closest_approach(&x, &rest, &faces, 0.3e-3);
        assert!(closest > 0.1e-3, "frame {frame}: the skin comes within {closest} m of itself");
        let (_, xb, fb) = sim.layer_surface("skin", "base");
        let (x, faces) = merged(&[(xe, fe), (xb, fb)]);
        assert!(crossing_pairs(&faces, &x).is_empty(), "frame {frame}: the epidermis crosses the base");
    }
    assert!(released > 0, "no kernel was released");
    let without = variant(rel, &[("contact: Some((thickness: 0.1, d_hat: 0.05)),", "")]);
    let mut sim = Simulation::new(&without);
    let first = (1..=without.scene.frames).find(|_| {
        sim.step();
        crossing(&mut sim) > 0
    });
    assert!(first.is_some(), "without contact the skin passes through itself");
}

/// The real character's elbow with contact (`scenes/character/elbow_contact_quick.ron`, its
/// first 3 frames: the hm08 arm's inner elbow bent by its own rig from 47 to about 84 degrees).
/// By frame 3 the arm's surface crosses itself at the crease (linear blend skinning). Every
/// frame converges, kernels are released there and held by soft springs, and the skin neither
/// crosses itself nor comes closer to itself than its 50 um thickness. Without contact the skin
/// crosses itself from frame 2.
#[test]
fn the_real_elbow_folds_its_skin_without_passing_through() {
    let rel = "character/elbow_contact_quick.ron";
    // (the run without contact side by side: much of a solve is serial)
    std::thread::scope(|s| {
        let without = s.spawn(|| {
            let without =
                variant(rel, &[("frames: 6,", "frames: 2,"), ("            contact: Some((thickness: 0.05)),\n", "")]);
            frames_crossing(&without, "inner_elbow", "skin")
        });
        elbow_with_contact(rel);
        assert!(without.join().unwrap() > 0, "without contact the skin passes through itself");
    });
}

fn elbow_with_contact(rel: &str) {
    let scene = variant(rel, &[("frames: 6,", "frames: 3,")]);
    let rest = scene.patches[0].layers[1].mesh.rest().to_vec();
    let measure = |sim: &mut Simulation, s: &FrameStats| {
        let released = s.patches[0].outcome.contact.expect("a contact report").released_kernels;
        let (_, x, faces) = sim.layer_mesh("inner_elbow", "skin");
        // (neighbours within 0.2 mm at rest are excluded: the edges are 0.6-2.8 mm)
        let closest = closest_approach(&x, &rest, &faces, 0.2e-3);
        let (_, xb, fb) = sim.layer_surface("inner_elbow", "surface");
        (crossing_pairs(&faces, &x).len(), closest, crossing_pairs(&fb, &xb).len(), released)
    };
    let frames = every_frame(&scene, measure);
    for (frame, &(crossing, closest, _, _)) in frames.iter().enumerate() {
        assert_eq!(crossing, 0, "frame {}: the skin crosses itself", frame + 1);
        assert!(closest > 0.05e-3, "frame {}: the skin comes within {closest} m of itself", frame + 1);
    }
    assert!(frames.iter().any(|m| m.2 > 0), "the arm does not cross itself");
    assert!(frames.iter().any(|m| m.3 > 0), "no kernel was released");
}
