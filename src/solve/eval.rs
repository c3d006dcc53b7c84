//! Evaluating a packed patch's elements: energies (line search), and energy + gradient + Hessian
//! assembled into the cached pattern. Elements run in parallel in fixed chunks; the scatter
//! and every sum run in element order, so results do not depend on the thread count.

use glam::DVec3;

use super::element::Part;
use super::elements::Elements;
use super::pattern::Pattern;
use super::scatter::Scatter;
use crate::physics::psd::Filter;

/// Energy by element kind (J), serialized as the report's `energy_*` columns.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct EnergyParts {
    #[serde(rename = "energy_membrane")]
    pub membrane: f64,
    /// Hinges, or the quadratic element and its Gaussian term.
    #[serde(rename = "energy_bending")]
    pub bending: f64,
    #[serde(rename = "energy_volume")]
    pub volume: f64,
    /// Attachment springs, KCK18 anchors and pins.
    #[serde(rename = "energy_springs")]
    pub springs: f64,
    /// Barrier contact (reported in the frame's `contact` object, not as a column of its own).
    #[serde(skip)]
    pub contact: f64,
}

impl EnergyParts {
    /// The elastic energy: the parts summed in this order.
    pub fn total(&self) -> f64 {
        self.membrane + self.bending + self.volume + self.springs + self.contact
    }

    /// Sums each kind's energy into its part, in the kinds' order: a part's first kind sets it.
    fn collect(kinds: impl Iterator<Item = (Part, f64)>) -> EnergyParts {
        let mut parts: [Option<f64>; 5] = [None; 5];
        for (part, e) in kinds {
            let slot = &mut parts[part as usize];
            *slot = Some(slot.map_or(e, |s| s + e));
        }
        let [membrane, bending, volume, springs, contact] = parts.map(|p| p.unwrap_or(0.0));
        EnergyParts { membrane, bending, volume, springs, contact }
    }
}

/// Energies only, by element kind.
pub fn energy(elements: &Elements, x: &[DVec3]) -> EnergyParts {
    EnergyParts::collect(elements.terms().into_iter().map(|t| (t.part(), t.energy(x))))
}

/// The result of one assembly.
#[derive(Clone, Copy, Debug, Default)]
pub struct Assembly {
    pub parts: EnergyParts,
    /// Sum of element force magnitudes: the scale the residual is measured against.
    pub force_scale: f64,
}

/// Assembles energy, the gradient over free DOFs (`grad`, length pattern.n) and the lower
/// triangle of the Hessian (`values`, length pattern.nnz()). Both buffers are overwritten.
pub fn assemble(
    el: &Elements,
    pattern: &Pattern,
    x: &[DVec3],
    filter: Filter,
    grad: &mut [f64],
    values: &mut [f64],
) -> Assembly {
    grad.iter_mut().for_each(|g| *g = 0.0);
    values.iter_mut().for_each(|v| *v = 0.0);
    let mut acc = Scatter { dof: &pattern.dof, grad, values, force: 0.0 };
    let terms = el.terms();
    let energies: Vec<(Part, f64)> =
        terms.iter().zip(&pattern.maps).map(|(t, map)| (t.part(), t.assemble(&mut acc, map, x, filter))).collect();
    Assembly { parts: EnergyParts::collect(energies.into_iter()), force_scale: acc.force }
}

/// Gradient of the elastic energy (springs included) at every vertex, fixed ones too: at a
/// prescribed vertex it is the reaction force the support exerts (with the opposite sign).
pub fn vertex_gradient(el: &Elements, x: &[DVec3]) -> Vec<DVec3> {
    let mut g = vec![DVec3::ZERO; x.len()];
    el.terms().iter().for_each(|t| t.add_gradient(x, &mut g));
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{edges, grid, GridPattern};
    use crate::physics::{gaussian_bending, QuadraticBending};
    use crate::solve::pattern::NONE;

    /// The symmetric matrix whose lower triangle the pattern stores.
    fn dense(pattern: &Pattern, values: &[f64]) -> nalgebra::DMatrix<f64> {
        let mut dense = nalgebra::DMatrix::<f64>::zeros(pattern.n, pattern.n);
        for c in 0..pattern.n {
            let span = pattern.col_ptr[c] as usize..pattern.col_ptr[c + 1] as usize;
            for (&r, &v) in pattern.row_idx[span.clone()].iter().zip(&values[span]) {
                dense[(r as usize, c)] = v;
                dense[(c, r as usize)] = v;
            }
        }
        dense
    }

    /// The assembled gradient and Hessian at x against central differences of `part` (the
    /// energy) and of the assembled gradient, over every free DOF.
    fn assert_derivatives(
        el: &Elements,
        pattern: &Pattern,
        x: &[DVec3],
        part: impl Fn(&[DVec3]) -> f64,
        grad: &[f64],
        values: &[f64],
    ) {
        let h = 1e-6;
        for v in 0..x.len() {
            for k in 0..3 {
                let d = pattern.dof[3 * v + k];
                if d == NONE {
                    continue;
                }
                let shifted = |s: f64| {
                    let mut y = x.to_vec();
                    y[v][k] += s;
                    y
                };
                let fd = (part(&shifted(h)) - part(&shifted(-h))) / (2.0 * h);
                assert!((fd - grad[d as usize]).abs() < 1e-6, "gradient at {v}.{k}: {fd} vs {}", grad[d as usize]);
                // Hessian column d against the central difference of gradients.
                let (mut gp, mut vp) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
                let (mut gm, mut vm) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
                assemble(el, pattern, &shifted(h), Filter::Exact, &mut gp, &mut vp);
                assemble(el, pattern, &shifted(-h), Filter::Exact, &mut gm, &mut vm);
                for r in 0..pattern.n as u32 {
                    let column = (gp[r as usize] - gm[r as usize]) / (2.0 * h);
                    let stored =
                        if pattern.position_of(r, d).is_some() { values[pattern.position(r, d) as usize] } else { 0.0 };
                    assert!((column - stored).abs() < 1e-5 * (1.0 + stored.abs()), "H[{r}, {d}]: {column} vs {stored}");
                }
            }
        }
    }

    /// The assembled quadratic bending gradient and Hessian, with its Gaussian term, against
    /// central differences of the energy, on a bent sheet with a held boundary (NONE entries
    /// in the maps).
    #[test]
    fn quadratic_bending_assembles_its_derivatives() {
        let m = grid(glam::DVec2::ONE, (5, 5), GridPattern::Equilateral, 0.0);
        let rigidity: Vec<_> = edges(&m.faces).iter().map(|e| (e.v, 2.0)).collect();
        let boundary = crate::mesh::boundary_vertices(&m.faces, m.rest.len());
        let quadratic = QuadraticBending::build(&m.faces, |i| m.rest[i as usize], &rigidity, &boundary);
        let gaussian = gaussian_bending::elements(&quadratic, &m.faces, |i| m.rest[i as usize], 0.3);
        assert!(!gaussian.is_empty());
        let el = Elements { quadratic, gaussian, ..Default::default() };
        let bending = |y: &[DVec3]| energy(&el, y).bending;
        let x: Vec<DVec3> = m
            .rest
            .iter()
            .enumerate()
            .map(|(i, p)| *p + DVec3::new(0.01 * (i as f64).sin(), 0.0, 0.1 * (3.0 * p.x).sin() * p.y))
            .collect();
        let fixed: Vec<[bool; 3]> = m.rest.iter().map(|p| [p.x == 0.0; 3]).collect();
        let tie: Vec<(u32, [bool; 3])> = (0..x.len() as u32).map(|i| (i, [false; 3])).collect();
        let pattern = Pattern::build(&x, &fixed, &tie, &el);
        let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
        let a = assemble(&el, &pattern, &x, Filter::Exact, &mut grad, &mut values);
        assert!((a.parts.bending - bending(&x)).abs() < 1e-15);
        assert_derivatives(&el, &pattern, &x, |y| energy(&el, y).bending, &grad, &values);
    }

    /// Issue 27: a slab whose tets share one dilatation per cell. The assembled gradient and
    /// Hessian (cells scattered through their 8-vertex maps, bottom held) against central
    /// differences of the energy, and the stability test's inertia against a dense eigen-solve,
    /// at a stretched state (stable) and a strongly compressed, sheared one.
    #[test]
    fn cells_assemble_their_derivatives_and_inertia() {
        use super::super::elements::{CellElem, TetElem};
        use crate::physics::tet::TetRest;
        use crate::physics::{ConstitutiveModel, Lame};
        let (m, _, _) = crate::mesh::tet_slab(glam::DVec2::new(2.0, 1.0), (2, 1), 0.0, &[(1.0, 2, 1.0)], None).unwrap();
        let lame = Lame::solid(1.0, 0.495);
        let tets: Vec<TetElem> = m
            .tets
            .iter()
            .map(|t| TetElem {
                v: *t,
                rest: TetRest::from_rest(t.map(|i| m.rest[i as usize]), glam::DMat3::IDENTITY).unwrap(),
                model: ConstitutiveModel::BazantHencky,
                lame,
            })
            .collect();
        let mut el = Elements::default();
        for c in 0..4u32 {
            let group: Vec<TetElem> = tets.iter().zip(&m.cells).filter(|(_, &k)| k == c).map(|(t, _)| *t).collect();
            el.cells.push(CellElem::from_tets(&group).expect("six tets over eight corners"));
        }
        el.tets = tets.into_iter().map(|t| TetElem { lame: Lame { lambda: 0.0, ..lame }, ..t }).collect();
        let fixed: Vec<[bool; 3]> = m.rest.iter().map(|p| [p.z < -0.99; 3]).collect();
        let tie: Vec<(u32, [bool; 3])> = (0..m.rest.len() as u32).map(|i| (i, [false; 3])).collect();
        let volume = |y: &[DVec3]| energy(&el, y).volume;
        for (stretch, shear) in [(1.05, 0.02), (0.55, 0.3)] {
            let x: Vec<DVec3> = m
                .rest
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let z = p.z + 1.0;
                    DVec3::new(p.x + shear * z * z, p.y + 0.01 * (i as f64).cos() * z, -1.0 + stretch * z)
                })
                .collect();
            let pattern = Pattern::build(&x, &fixed, &tie, &el);
            let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
            let a = assemble(&el, &pattern, &x, Filter::Exact, &mut grad, &mut values);
            assert!((a.parts.volume - volume(&x)).abs() < 1e-14);
            assert_derivatives(&el, &pattern, &x, volume, &grad, &values);
            // Inertia: the LDL^T's count against the dense spectrum.
            let dense = dense(&pattern, &values);
            let negative = nalgebra::SymmetricEigen::new(dense).eigenvalues.iter().filter(|&&l| l < 0.0).count();
            let mut chol = super::super::linear::CholeskySolver::analyze(&pattern);
            let verdict =
                super::super::stability::test(&pattern, &mut chol, &values, super::super::StabilityTest::Inertia)
                    .expect("an LDL^T");
            match verdict {
                super::super::stability::Verdict::Stable => assert_eq!(negative, 0, "{stretch}"),
                super::super::stability::Verdict::Unstable { negative: k, .. } => assert_eq!(k, negative, "{stretch}"),
            }
            if stretch < 1.0 {
                assert!(negative > 0, "the compressed, sheared slab is unstable: {negative}");
            }
        }
    }

    /// Issue 64: contact pairs scatter their exact derivatives through the pattern (a point
    /// over a triangle, two crossing edges, one vertex held), and the stability test's inertia
    /// counts the barrier's negative curvature as a dense eigen-solve does.
    #[test]
    fn contact_pairs_assemble_their_derivatives_and_inertia() {
        use crate::contact::{Barrier, ContactPairs, Pair, Primitives};
        let barrier = Barrier { offset: 0.1, reach: 0.3 };
        let x = vec![
            DVec3::new(0.3, 0.3, 0.25),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.1, 0.0),
            DVec3::new(0.2, 0.9, 0.05),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(3.0, 0.1, 0.0),
            DVec3::new(2.4, -0.5, 0.3),
            DVec3::new(2.6, 0.5, 0.25),
        ];
        let pairs = vec![
            Pair { v: [0, 1, 2, 3], kind: Primitives::PointTriangle, barrier, eps: 0.0 },
            Pair { v: [4, 5, 6, 7], kind: Primitives::EdgeEdge, barrier, eps: 1e-3 },
        ];
        let el = Elements { contacts: ContactPairs { pairs, stiffness: 3.0 }, ..Default::default() };
        let mut fixed = vec![[false; 3]; x.len()];
        fixed[1] = [true; 3];
        let tie: Vec<(u32, [bool; 3])> = (0..x.len() as u32).map(|i| (i, [false; 3])).collect();
        let pattern = Pattern::build(&x, &fixed, &tie, &el);
        let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
        let a = assemble(&el, &pattern, &x, Filter::Exact, &mut grad, &mut values);
        assert!(a.parts.contact > 0.0 && a.parts.total() == a.parts.contact);
        assert_derivatives(&el, &pattern, &x, |y| energy(&el, y).contact, &grad, &values);
        let eigen = nalgebra::SymmetricEigen::new(dense(&pattern, &values)).eigenvalues;
        let scale = eigen.iter().fold(0.0f64, |m, l| m.max(l.abs()));
        let negative = eigen.iter().filter(|&&l| l < -1e-12 * scale).count();
        assert!(negative > 0, "the exact barrier Hessian is indefinite here: {eigen}");
        let mut chol = super::super::linear::CholeskySolver::analyze(&pattern);
        // (the barrier Hessian of one pair has rank well below 12: shift the zero eigenvalues
        // up so that the LDL^T sees only the signs that matter)
        let mut shifted = values.clone();
        for &d in &pattern.diag {
            shifted[d as usize] += 1e-9 * scale;
        }
        match super::super::stability::test(&pattern, &mut chol, &shifted, super::super::StabilityTest::Inertia)
            .expect("an LDL^T")
        {
            super::super::stability::Verdict::Stable => assert_eq!(negative, 0),
            super::super::stability::Verdict::Unstable { negative: k, .. } => assert_eq!(k, negative),
        }
    }
}
