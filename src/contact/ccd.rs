//! Conservative continuous collision detection: additive CCD (Li et al. 2021, "Codimensional
//! incremental potential contact", Algorithm 1). The pair's gap d - xi can shrink no faster
//! than the largest relative speed of its primitives, l_p; stepping time by a fraction of
//! gap / l_p therefore never passes the first time the gap closes. It returns a time no later
//! than the true time of impact (the line search starts there), or None when the gap stays open
//! over the whole step.

use super::distance::{squared_distance, Primitives};

/// The pair's displacements less their mean (distance is blind to a common translation), and
/// l_p: the most the pair's distance can shrink over the step (its two primitives' largest
/// relative displacements, summed).
pub fn relative_motion(kind: Primitives, dx: &[[f64; 3]; 4]) -> ([[f64; 3]; 4], f64) {
    let mean: [f64; 3] = std::array::from_fn(|k| dx.iter().map(|d| d[k]).sum::<f64>() / 4.0);
    let p: [[f64; 3]; 4] = std::array::from_fn(|i| std::array::from_fn(|k| dx[i][k] - mean[k]));
    let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let l_p = match kind {
        Primitives::PointTriangle => norm(&p[0]) + norm(&p[1]).max(norm(&p[2])).max(norm(&p[3])),
        Primitives::EdgeEdge => norm(&p[0]).max(norm(&p[1])) + norm(&p[2]).max(norm(&p[3])),
    };
    (p, l_p)
}

/// The time in (0, t_max] at which the pair's gap has first shrunk below `s` times its start
/// (s = 0.1: the step keeps a tenth of the gap), or None if it stays above that through t_max.
/// `x`: positions at t = 0; `dx`: displacements over t in [0, 1]; `offset`: the thickness xi.
pub fn additive_toi(kind: Primitives, x: &[[f64; 3]; 4], dx: &[[f64; 3]; 4], offset: f64, t_max: f64) -> Option<f64> {
    const S: f64 = 0.1;
    const MAX_STEPS: u32 = 100_000;
    let (p, l_p) = relative_motion(kind, dx);
    if l_p == 0.0 {
        return None;
    }
    let gap = |y: &[[f64; 3]; 4]| {
        let d2 = squared_distance(kind, y);
        (d2 - offset * offset) / (d2.sqrt() + offset)
    };
    // (the boxes' gap is a lower bound on the pair's: when even it needs more than the step to
    // close by 1 - s, the first step below leaves t_max with no further test. Most listed
    // pairs end here without their closest features.)
    let lower = super::distance::box_gap_squared(kind, x).sqrt() - offset;
    if lower > 0.0 && (1.0 - S) * lower / l_p > t_max {
        return None;
    }
    let mut y = *x;
    let g0 = gap(&y);
    if g0 <= 0.0 {
        return Some(0.0);
    }
    let target = S * g0;
    let mut t = 0.0;
    let mut t_l = (1.0 - S) * g0 / l_p;
    if t_l > t_max {
        return None;
    }
    for _ in 0..MAX_STEPS {
        for (yi, pi) in y.iter_mut().zip(&p) {
            for k in 0..3 {
                yi[k] += t_l * pi[k];
            }
        }
        let g = gap(&y);
        if t > 0.0 && g < target {
            return Some(t);
        }
        t += t_l;
        if t > t_max {
            return None;
        }
        t_l = 0.9 * g / l_p;
    }
    // (a pair creeping at round-off: report the time reached, which is still before impact)
    Some(t)
}
