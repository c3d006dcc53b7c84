//! VALIDATION.md cases 7 and 8: a stiff shell film on a soft tetrahedral substrate (the H15
//! construction) in plane strain, against wrinkling theory. Periodic domains of eight expected
//! wavelengths (the neighbouring mode numbers are 11-14 % away, so the 3 % and 5 % wavelength
//! tolerances test which mode the solver selects), 20 film elements per wavelength, substrates
//! graded towards the surface. Substrates at nu_s = 0.45 (tetrahedra with their own lambda term)
//! and at VALIDATION.md's 0.495 (one dilatation per cell of six tetrahedra, `physics::cell`: per
//! tetrahedron the mesh locks there, the case-8 wavelength 11 % short and onsets 19-44 % late);
//! the case-8 references for 0.45 come from the same layered-elasticity solution that
//! reproduces VALIDATION.md's 0.495 table (`film::layered_theory`, unit-tested).
//! `cargo test --release -p skinsim-cli --test h15_validation -- --nocapture` prints the figures.

use skinsim::physics::ConstitutiveModel;
use skinsim::solve::Precision;
use skinsim_tools::film::{FilmResult, FilmSubstrate};

fn report(name: &str, r: &FilmResult) {
    println!(
        "{name}: wavelength {:.3} h (theory {:.3}, {:+.2} %), onset {:.5} (theory {:.5}, {:+.2} %), \
         amplitude errors {}; {} increments converged: {}, {:.0} ms per increment, {} Newton iterations",
        r.wavelength,
        r.expected_wavelength,
        100.0 * r.wavelength_error(),
        r.onset,
        r.expected_onset,
        100.0 * r.onset_error(),
        r.amplitude_errors
            .iter()
            .map(|(t, e)| format!("{t} eps_c: {:+.2} %", 100.0 * e))
            .collect::<Vec<_>>()
            .join(", "),
        r.series.len(),
        r.all_converged,
        1e3 * r.wall_per_increment_s,
        r.newton_iterations,
    );
}

fn case_7(ratio: f64, substrate_poisson: f64) {
    let mut setup = FilmSubstrate::deep(ratio, 8, 20, 20);
    setup.grading = 20.0;
    setup.substrate_poisson = substrate_poisson;
    let r = setup.run().unwrap();
    report(&format!("case 7, Ebar_f / Ebar_s = {ratio}, nu_s = {substrate_poisson}"), &r);
    assert_case_7(&r);
}

fn assert_case_7(r: &FilmResult) {
    assert!(r.all_converged);
    assert!(r.wavelength_error().abs() < 0.03, "wavelength {:+.3}", r.wavelength_error());
    assert!(r.onset_error().abs() < 0.05, "onset {:+.3}", r.onset_error());
    assert_eq!(r.amplitude_errors.len(), 3);
    assert!(r.worst_amplitude_error() < 0.10, "{:?}", r.amplitude_errors);
}

#[test]
fn case_7_stiffness_ratio_1000() {
    // lambda_c / h = 43.565, eps_c = 0.005200.
    case_7(1000.0, 0.45);
}

#[test]
fn case_7_nearly_incompressible_substrate() {
    // nu_s = 0.495, the same mesh: the default volume element there is the cell.
    case_7(1000.0, 0.495);
}

#[test]
fn case_7_in_mixed_precision() {
    // Issue 25 item 2: the Newton factor in f32, each step refined in f64 (the stability test's
    // inertia stays f64): the same tolerances.
    let mut setup = FilmSubstrate::deep(1000.0, 8, 20, 20);
    (setup.grading, setup.precision) = (20.0, Precision::F32);
    let r = setup.run().unwrap();
    report("case 7, Ebar_f / Ebar_s = 1000, mixed precision", &r);
    assert_case_7(&r);
}

#[test]
fn case_7_with_ten_graded_depth_elements() {
    // Issue 25 item 3: how few substrate elements through 1.5 lambda_c still hold case 7 (graded
    // 20:1 towards the film). Ten do (onset +3.5 %, amplitude -3.5 %); six do not (onset +9 %),
    // and steeper grading makes a coarse substrate worse: `depth_resolution_table`.
    let mut setup = FilmSubstrate::deep(1000.0, 8, 20, 10);
    setup.grading = 20.0;
    let r = setup.run().unwrap();
    report("case 7, Ebar_f / Ebar_s = 1000, 10 depth elements", &r);
    assert_case_7(&r);
}

#[test]
fn case_7_with_the_substrate_coarsening_every_half_wavelength() {
    // Issue 25 item 3: the substrate's grid halves along x every lambda_c / 2 below the film
    // (transition cells between the grids). Onset +1.5 % (uniform: +0.7 %), amplitudes within
    // 1.4 %; every lambda_c / 4 fails (onset +5.6 %): `coarsening_table`.
    let mut setup = FilmSubstrate::deep(1000.0, 8, 20, 20);
    (setup.grading, setup.coarsen) = (20.0, Some(0.5));
    let r = setup.run().unwrap();
    report("case 7, Ebar_f / Ebar_s = 1000, coarsening every lambda / 2", &r);
    assert_case_7(&r);
    assert!(r.vertices < 6762 * 4 / 5, "the grid did not coarsen: {} vertices", r.vertices);
}

#[test]
fn case_8_with_the_substrate_coarsening_every_half_wavelength() {
    // H = 0.5 lambda_inf on a rigid base, case 8's mesh: onset +2.8 % as uniform.
    let mut setup = FilmSubstrate::on_rigid(0.5, 0.45, 20, 10);
    setup.coarsen = Some(0.5);
    let r = setup.run().unwrap();
    report("case 8, H / lambda_inf = 0.5, coarsening every lambda / 2", &r);
    assert!(r.all_converged);
    assert!(r.wavelength_error().abs() < 0.05, "wavelength {:+.3}", r.wavelength_error());
    assert!(r.onset_error().abs() < 0.05, "onset {:+.3}", r.onset_error());
    assert!(r.vertices < 3542, "the grid did not coarsen: {} vertices", r.vertices);
}

/// The errors of cases 7 and 8 (H = 0.5 lambda_inf) against the substrate's depth elements and
/// grading (issue 25 item 3), printed:
/// `cargo test --release -p skinsim-cli --test h15_validation -- --ignored --nocapture`.
#[test]
#[ignore]
fn depth_resolution_table() {
    for (elements, grading) in [(20, 20.0), (10, 20.0), (6, 20.0), (4, 20.0), (3, 20.0), (6, 60.0), (4, 100.0)] {
        let mut deep = FilmSubstrate::deep(1000.0, 8, 20, elements);
        deep.grading = grading;
        let r = deep.run().unwrap();
        report(&format!("case 7, {elements} depth elements graded {grading}:1, {} tets", r.tets), &r);
        let mut rigid = FilmSubstrate::on_rigid(0.5, 0.45, 20, elements.min(10));
        rigid.grading = grading;
        let r = rigid.run().unwrap();
        report(&format!("case 8, H = 0.5 lambda_inf, {} depth elements graded {grading}:1", elements.min(10)), &r);
    }
}

/// Cases 7 and 8 (H = 0.5 lambda_inf) with the substrate's grid halving along x every
/// 0.25, 0.5 and 1 lambda_c below the film, and uniform (issue 25 item 3), printed:
/// `cargo test --release -p skinsim-cli --test h15_validation -- --ignored --nocapture coarsening_table`.
#[test]
#[ignore]
fn coarsening_table() {
    for every in [None, Some(0.25), Some(0.39), Some(0.5), Some(1.0)] {
        let mut deep = FilmSubstrate::deep(1000.0, 8, 20, 20);
        (deep.grading, deep.coarsen) = (20.0, every);
        let r = deep.run().unwrap();
        report(&format!("case 7, coarsening every {every:?} lambda, {} vertices, {} tets", r.vertices, r.tets), &r);
        // Case 8's test set-up (10 uniform elements through H).
        let mut rigid = FilmSubstrate::on_rigid(0.5, 0.45, 20, 10);
        rigid.coarsen = every;
        let r = rigid.run().unwrap();
        report(&format!("case 8, H = 0.5 lambda_inf, coarsening every {every:?} lambda, {} vertices", r.vertices), &r);
    }
}

#[test]
fn case_7_stiffness_ratio_10000() {
    // lambda_c / h = 93.86, eps_c = 0.001120.
    case_7(10000.0, 0.45);
}

#[test]
fn case_8_finite_depth_on_a_rigid_base() {
    case_8(0.45);
}

#[test]
fn case_8_nearly_incompressible_as_validation_states_it() {
    // VALIDATION.md's table itself (nu_s = 0.495).
    case_8(0.495);
}

#[test]
fn case_8_nearly_incompressible_with_each_model() {
    // The cell's lambda term for Stable Neo-Hookean (exact split) and corotational (J - 1 in
    // place of tr S - 3), H / lambda_inf = 0.2 (the per-tet element: wavelength -11 %, onset +36 %).
    for model in [ConstitutiveModel::StableNeoHookean, ConstitutiveModel::Corotational] {
        let mut setup = FilmSubstrate::on_rigid(0.2, 0.495, 20, 8);
        setup.substrate_model = model;
        let r = setup.run().unwrap();
        report(&format!("case 8, H / lambda_inf = 0.2, nu_s = 0.495, {model:?}"), &r);
        assert!(r.all_converged);
        assert!(r.wavelength_error().abs() < 0.05, "{model:?}: wavelength {:+.3}", r.wavelength_error());
        assert!(r.onset_error().abs() < 0.05, "{model:?}: onset {:+.3}", r.onset_error());
    }
}

fn case_8(nu: f64) {
    for (depth, elements) in [(0.2, 8), (0.3, 8), (0.5, 10)] {
        let r = FilmSubstrate::on_rigid(depth, nu, 20, elements).run().unwrap();
        report(&format!("case 8, H / lambda_inf = {depth}, nu_s = {nu}"), &r);
        assert!(r.all_converged);
        assert!(r.wavelength_error().abs() < 0.05, "H {depth}: wavelength {:+.3}", r.wavelength_error());
        assert!(r.onset_error().abs() < 0.05, "H {depth}: onset {:+.3}", r.onset_error());
    }
}
