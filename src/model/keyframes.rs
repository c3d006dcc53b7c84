//! Keyframed values: what every motion and rig clip is driven by.

/// How a value moves between two keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Interpolation {
    #[default]
    Linear,
    /// Smoothstep (3t^2 - 2t^3): zero rate at every keyframe, so a weight eases in and out.
    Smooth,
}

/// Keyframes (frame, value), interpolated between keys and held constant outside their range.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes(pub Vec<(u32, f64)>);

impl Keyframes {
    /// The value at `frame` with the given interpolation between keys (0 without keys).
    pub fn at(&self, frame: f64, interpolation: Interpolation) -> f64 {
        let k = &self.0;
        let (Some(first), Some(last)) = (k.first(), k.last()) else { return 0.0 };
        if frame <= first.0 as f64 {
            return first.1;
        }
        let Some(w) = k.windows(2).find(|w| frame <= w[1].0 as f64) else { return last.1 };
        let ((f0, v0), (f1, v1)) = ((w[0].0 as f64, w[0].1), (w[1].0 as f64, w[1].1));
        match interpolation {
            Interpolation::Linear => v0 + (v1 - v0) * (frame - f0) / (f1 - f0),
            Interpolation::Smooth => {
                let t = (frame - f0) / (f1 - f0);
                v0 + (v1 - v0) * (t * t * (3.0 - 2.0 * t))
            }
        }
    }
}
