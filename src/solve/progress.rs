//! What both Newton loops (`newton.rs`, `constrained.rs`) measure at every iterate, written once:
//! the residual against the internal force scale, H15's adaptive projection switch and the
//! convergence test (the tolerance, or the round-off floor).

use crate::physics::psd::Filter;
use crate::physics::Projection;

/// Adaptive projection: below this relative residual the exact Hessian is tried.
pub(super) const ADAPTIVE_SWITCH: f64 = 1e-3;
/// Iterations without progress that signal the round-off floor.
pub(super) const STALL: usize = 4;
/// No progress: a residual above this fraction of the one STALL iterations back.
pub(super) const PROGRESS: f64 = 0.5;
/// Smallest force scale, relative to the elements' forces at unit strain.
pub(super) const FORCE_FLOOR: f64 = 1e-6;

pub(super) struct Progress {
    tolerance: f64,
    projection: Projection,
    /// The force scale of a 1e-6 strain (N).
    floor: f64,
    /// No free DOF: converged as it stands.
    empty: bool,
    history: Vec<f64>,
    /// H15's adaptive policy: project until the gradient has fallen below ADAPTIVE_SWITCH, then
    /// use the exact Hessian until it fails (not positive definite, or not a descent direction).
    pub projecting: bool,
}

impl Progress {
    /// `energy_scale`: the elements' energy at unit strain (J); `length_scale`: the patch's size.
    pub(super) fn new(
        tolerance: f64,
        projection: Projection,
        energy_scale: f64,
        length_scale: f64,
        dofs: usize,
    ) -> Self {
        let floor = FORCE_FLOOR * energy_scale / length_scale.max(f64::MIN_POSITIVE);
        Progress { tolerance, projection, floor, empty: dofs == 0, history: Vec::new(), projecting: true }
    }

    /// The element-Hessian filter for the next assembly.
    pub(super) fn filter(&self) -> Filter {
        element_filter(self.projection, self.projecting)
    }

    /// The gradient norm relative to the internal forces, but never to less than those of a
    /// 1e-6 strain: an unloaded patch has only round-off forces and is converged.
    pub(super) fn residual(&self, gnorm: f64, force_scale: f64) -> f64 {
        let reference = force_scale.max(self.floor);
        if reference > 0.0 {
            (gnorm / reference).max(0.0)
        } else {
            0.0
        }
    }

    /// Whether no iterate was recorded since the start (or the last restart).
    pub(super) fn first(&self) -> bool {
        self.history.is_empty()
    }

    /// Records an iterate's residual: true when it is converged, at the tolerance or at the
    /// round-off floor (within 1000x of the tolerance and no progress over the last STALL
    /// iterations).
    pub(super) fn record(&mut self, residual: f64) -> bool {
        if residual < ADAPTIVE_SWITCH {
            self.projecting = false;
        }
        self.history.push(residual);
        let h = &self.history;
        let stalled =
            h.len() > STALL && residual <= 1e3 * self.tolerance && residual >= PROGRESS * h[h.len() - 1 - STALL];
        self.empty || residual <= self.tolerance || stalled
    }

    /// Forgets the recorded residuals (the solve moved to a new start: a saddle was left).
    pub(crate) fn restart(&mut self) {
        self.history.clear();
    }
}

/// The element-Hessian filter of a projection policy; `projecting`: H15's adaptive policy is in
/// its projected phase.
pub(super) fn element_filter(projection: Projection, projecting: bool) -> Filter {
    match projection {
        Projection::None => Filter::Exact,
        Projection::Clamp => Filter::Clamp,
        Projection::Abs => Filter::Abs,
        Projection::Adaptive if !projecting => Filter::Exact,
        Projection::Adaptive => Filter::Clamp,
    }
}
