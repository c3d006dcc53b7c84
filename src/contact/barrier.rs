//! The log barrier on a pair's squared distance, with a thickness offset (codimensional IPC:
//! Li et al. 2021, sec. 4), and the edge-edge mollifier (IPC: Li et al. 2020, sec. 4.3).
//!
//! With offset xi and activation distance d_hat, the barrier acts on z = d^2 - xi^2 with
//! z_hat = (xi + d_hat)^2 - xi^2 = 2 xi d_hat + d_hat^2, so it is active for d < xi + d_hat
//! and grows without bound as d falls to xi:
//!   b(z) = -(z - z_hat)^2 ln(z / z_hat) for 0 < z < z_hat, 0 beyond (IPC eq. 6, C2 at z_hat).

use num_dual::DualNum;

/// The barrier's reach and offset for one pair.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Barrier {
    /// The thickness offset xi (m): the distance the barrier keeps the surfaces apart.
    pub offset: f64,
    /// The activation distance d_hat (m) beyond the offset.
    pub reach: f64,
}

impl Barrier {
    /// z_hat: the barrier's support in z = d^2 - xi^2.
    pub fn z_hat(&self) -> f64 {
        self.reach * (2.0 * self.offset + self.reach)
    }

    /// z = d^2 - xi^2 of a squared distance.
    pub fn z<D: DualNum<Primitive = f64> + Copy>(&self, d2: D) -> D {
        d2 - self.offset * self.offset
    }

    /// Whether a squared distance is inside the barrier's support.
    pub fn active(&self, d2: f64) -> bool {
        self.z(d2) < self.z_hat()
    }

    /// b(z); infinite at or below z = 0 (the surfaces at the offset or through it).
    pub fn value<D: DualNum<Primitive = f64> + Copy>(&self, z: D) -> D {
        let zh = self.z_hat();
        if z.re() >= zh {
            D::from(0.0)
        } else if z.re() <= 0.0 {
            D::from(f64::INFINITY)
        } else {
            let t = z - zh;
            -(t * t) * (z / zh).ln()
        }
    }

    /// d^2 b / dz^2 at z in (0, z_hat) (the stiffness's scale, IPC's kappa_min).
    pub fn curvature(&self, z: f64) -> f64 {
        let zh = self.z_hat();
        if z <= 0.0 || z >= zh {
            return 0.0;
        }
        let t = z - zh;
        -2.0 * (z / zh).ln() - 4.0 * t / z + t * t / (z * z)
    }
}

/// The edge-edge mollifier m(c) on c = |ea x eb|^2 (IPC eq. 12): (2 - c / eps) c / eps below
/// eps, 1 above, so that the barrier of nearly parallel edges vanishes smoothly where their
/// distance type changes. `eps` = 1e-3 |ea|^2 |eb|^2 at rest.
pub fn mollifier<D: DualNum<Primitive = f64> + Copy>(c: D, eps: f64) -> D {
    if c.re() >= eps {
        D::from(1.0)
    } else {
        let r = c / eps;
        (-r + 2.0) * r
    }
}

/// The mollifier's threshold for two edges of rest lengths la, lb.
pub fn mollifier_threshold(la: f64, lb: f64) -> f64 {
    1e-3 * la * la * lb * lb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barrier_is_c2_at_its_reach_and_unbounded_at_the_offset() {
        let b = Barrier { offset: 1e-3, reach: 5e-4 };
        let zh = b.z_hat();
        assert!((zh - ((1.5e-3f64).powi(2) - 1e-6)).abs() < 1e-18);
        // Value, slope and curvature all tend to 0 at z_hat.
        let near = zh * (1.0 - 1e-6);
        assert!(b.value(near) < 1e-20 && b.curvature(near) < 1e-5);
        assert!(b.value(zh * 1e-12) > b.value(zh * 1e-6));
        assert!(b.value(0.0f64).is_infinite() && b.value(-1.0f64).is_infinite());
        // Curvature against a central difference of the value.
        let z = 0.3 * zh;
        let h = 1e-6 * zh;
        let fd = (b.value(z + h) - 2.0 * b.value(z) + b.value(z - h)) / (h * h);
        assert!((fd - b.curvature(z)).abs() < 1e-4 * b.curvature(z), "{fd} {}", b.curvature(z));
    }

    #[test]
    fn mollifier_is_c1_at_its_threshold() {
        let eps = 2.0;
        assert_eq!(mollifier(eps, eps), 1.0);
        assert!((mollifier(eps * (1.0 - 1e-8), eps) - 1.0).abs() < 1e-15);
        assert_eq!(mollifier(0.0, eps), 0.0);
        let d = num_dual::Dual64::from_re(eps * (1.0 - 1e-9)).derivative();
        assert!(mollifier(d, eps).eps.abs() < 1e-8);
    }
}
