//! A pin: a zero-rest-length spring from one vertex to a fixed point, E = k / 2 |x_v - p|^2
//! (PHYSICS.md 1.5), with a stiffness per axis so that a pin may hold a vertex in a plane or
//! on a line and leave it free along the rest. The seam's smallest kind: this file and one
//! registration line in `elements/mod.rs`.

use glam::DVec3;
use nalgebra::{SMatrix, SVector};

use crate::physics::psd::Filter;
use crate::solve::element::{renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct PinElem {
    pub v: [u32; 1],
    /// Stiffness along x, y and z (N/m).
    pub k: DVec3,
    pub target: DVec3,
}

impl Element for PinElem {
    type Vertices = [u32; 1];
    type Local = Derivatives<3>;
    const PART: Part = Part::Springs;
    fn vertices(&self) -> [u32; 1] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        let r = x[self.v[0] as usize] - self.target;
        0.5 * self.k.dot(r * r)
    }
    fn eval(&self, x: &[DVec3], _filter: Filter) -> Self::Local {
        let r = x[self.v[0] as usize] - self.target;
        let g = self.k * r;
        let h = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(self.k.x, self.k.y, self.k.z));
        (0.5 * self.k.dot(r * r), SVector::<f64, 3>::new(g.x, g.y, g.z), h)
    }
    fn unit_energy(&self, length: f64) -> f64 {
        self.k.max_element() * length * length
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        PinElem { v: renumbered(self.v, to), ..*self }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::element::Term;
    use crate::solve::elements::Elements;
    use crate::solve::scatter::Local;

    /// The gradient and Hessian against central differences of the energy, at a point off the
    /// target in every axis, through the element and through the registered list.
    #[test]
    fn pin_derivatives_match_differences() {
        let pin = PinElem { v: [1], k: DVec3::new(2.0, 0.0, 5.0), target: DVec3::new(0.1, -0.2, 0.3) };
        let x = vec![DVec3::ZERO, DVec3::new(0.7, 0.4, -0.9)];
        let (e, g, h) = pin.eval(&x, Filter::Exact);
        assert_eq!(e, pin.energy(&x));
        let d = 1e-6;
        for a in 0..3 {
            let shifted = |s: f64| {
                let mut y = x.clone();
                y[1][a] += s;
                y
            };
            let fd = (pin.energy(&shifted(d)) - pin.energy(&shifted(-d))) / (2.0 * d);
            assert!((fd - g[a]).abs() < 1e-8, "gradient {a}: {fd} vs {}", g[a]);
            for b in 0..3 {
                let column = (pin.eval(&shifted(d), Filter::Exact).1[b] - pin.eval(&shifted(-d), Filter::Exact).1[b])
                    / (2.0 * d);
                assert!((column - h[(b, a)]).abs() < 1e-8, "H[{b}, {a}]: {column} vs {}", h[(b, a)]);
            }
        }
        // Registered: the list's energy and reaction force are the element's, in the springs part.
        let el = Elements { pins: vec![pin], ..Default::default() };
        assert_eq!(el.pins.part(), Part::Springs);
        assert_eq!(crate::solve::eval::energy(&el, &x).springs, e);
        let reaction = crate::solve::eval::vertex_gradient(&el, &x);
        assert_eq!(reaction[1], DVec3::new(g[0], g[1], g[2]));
        assert_eq!(pin.eval(&x, Filter::Exact).gradient_norm(), g.norm());
    }

    /// Through the whole solver: a sheet held at its edges, its centre pinned 2 cm up along z
    /// only. The pin joins the pattern, the assembly and the line search: Newton converges,
    /// the pinned vertex rises towards its target and keeps its x and y.
    #[test]
    fn a_pinned_sheet_solves() {
        use crate::mesh::{grid, GridPattern};
        use crate::physics::{ConstitutiveModel, HingeModel, Lame};
        use crate::solve::{solve_frame, PackedPatch, SolverSettings};
        let m = grid(glam::DVec2::ONE, (8, 8), GridPattern::Equilateral, 0.0);
        let edge = |p: DVec3| p.x <= 1e-9 || p.x >= 1.0 - 1e-9 || p.y <= 1e-9 || p.y >= 1.0 - 1e-9;
        let lame = Lame::plane_stress(1.0, 0.3);
        let bending = Some((HingeModel::Tan, 1e-6));
        let mut packed =
            PackedPatch::from_shell(&m, ConstitutiveModel::BazantHencky, lame, 1e-2, bending, |p| [edge(p); 3]);
        let centre = (0..m.rest.len()).min_by(|&a, &b| {
            let d = |i: usize| m.rest[i].truncate().distance(glam::DVec2::splat(0.5));
            d(a).total_cmp(&d(b))
        });
        let c = centre.unwrap();
        let target = m.rest[c] + DVec3::new(0.3, 0.3, 0.02);
        packed.elements.pins.push(PinElem { v: [c as u32], k: DVec3::new(0.0, 0.0, 1.0), target });
        let out = solve_frame(&mut packed, &SolverSettings::default(), 1.0).expect("a solve");
        let x = packed.state.x[c];
        assert!(out.converged && out.parts.springs > 0.0, "{out:?}");
        assert!(x.z > 0.002 && x.z < 0.02, "pulled up, held back by the membrane: {x}");
        assert!((x.truncate() - m.rest[c].truncate()).length() < 1e-3, "x and y are free of the pin: {x}");
    }
}
