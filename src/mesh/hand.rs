//! A procedural hand-like body for the character scenes (issue 24; `skinsim asset hand` writes
//! it as an OBJ): an arm that flattens into a palm, and two fingers, each a closed tube along x
//! with its seam on the back (+z). Every tube is its own UV island: u = x, v = arc length
//! around from the seam, the islands side by side in v. Lengths in the caller's unit.

use std::f64::consts::TAU;

use glam::{DVec2, DVec3};

use super::SurfaceMesh;

/// The shape and resolution of the hand (scene length units, mm in the shipped scenes).
#[derive(Clone, Copy, Debug)]
pub struct HandShape {
    /// Vertices around and cells along each finger.
    pub finger_cells: (u32, u32),
    /// Vertices around and cells along the arm and palm.
    pub arm_cells: (u32, u32),
}

/// The arm: round (radius 12) up to x = -45, flattening to a palm 44 wide and 16 thick from
/// x = -30 on, from x = -90 to 0.
pub(crate) const ARM: (f64, f64) = (-90.0, 0.0);
/// The fingers: radius 7, from x = -5 (inside the palm) to 75, at y = -10 and +10.
pub(crate) const FINGER_RADIUS: f64 = 7.0;
pub(crate) const FINGER: (f64, f64) = (-5.0, 75.0);
pub(crate) const FINGER_Y: [f64; 2] = [-10.0, 10.0];
/// The gap between UV islands (in v).
pub(crate) const ISLAND_GAP: f64 = 4.0;

/// The arm's elliptic section (half-width in y, half-height in z) at x.
fn arm_section(x: f64) -> (f64, f64) {
    let t = ((x + 45.0) / 15.0).clamp(0.0, 1.0);
    let s = t * t * (3.0 - 2.0 * t); // smoothstep: no kink in the surface
    (12.0 + s * (22.0 - 12.0), 12.0 + s * (8.0 - 12.0))
}

/// The hand: arm and palm, then the two fingers, as one mesh of three closed tubes.
pub fn hand(shape: HandShape) -> SurfaceMesh {
    let mut m = SurfaceMesh::default();
    let mut v0 = 0.0;
    v0 = tube(&mut m, ARM, shape.arm_cells, v0, |x| (DVec2::ZERO, arm_section(x))) + ISLAND_GAP;
    for y in FINGER_Y {
        let r = FINGER_RADIUS;
        v0 = tube(&mut m, FINGER, shape.finger_cells, v0, move |_| (DVec2::new(y, 0.0), (r, r))) + ISLAND_GAP;
    }
    m
}

/// Appends a closed tube along x over `span`: `cells` = (vertices around, cells along), its
/// section at x centred on `section(x).0` (y, z) with half-axes `section(x).1`. Returns the
/// largest v of its island (whose v starts at `v0`).
fn tube(
    m: &mut SurfaceMesh,
    span: (f64, f64),
    cells: (u32, u32),
    v0: f64,
    section: impl Fn(f64) -> (DVec2, (f64, f64)),
) -> f64 {
    let (around, along) = cells;
    let base = m.rest.len() as u32;
    let mut v_max = v0;
    for i in 0..=along {
        let x = span.0 + (span.1 - span.0) * i as f64 / along as f64;
        let (c, (ry, rz)) = section(x);
        // The angle from +z towards +y; v is the arc length from the seam at +z.
        let ring: Vec<DVec3> = (0..around)
            .map(|j| {
                let a = TAU * j as f64 / around as f64;
                DVec3::new(x, c.x + ry * a.sin(), c.y + rz * a.cos())
            })
            .collect();
        let mut v = v0;
        for (j, p) in ring.iter().enumerate() {
            if j > 0 {
                v += (*p - ring[j - 1]).length();
            }
            m.rest.push(*p);
            m.uv.push(DVec2::new(x, v));
        }
        v_max = v_max.max(v + (ring[0] - ring[ring.len() - 1]).length());
    }
    super::bodies::tube_faces(&mut m.faces, base, around, around, along);
    v_max
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_closed_tubes_on_separate_islands() {
        let m = hand(HandShape { finger_cells: (24, 20), arm_cells: (32, 18) });
        assert_eq!(m.rest.len(), (32 * 19 + 2 * 24 * 21) as usize);
        assert_eq!(m.faces.len(), (2 * 32 * 18 + 2 * 2 * 24 * 20) as usize);
        // The finger islands start above the arm's in v, without overlap.
        let arm_top = m.uv[..32 * 19].iter().map(|p| p.y).fold(0.0, f64::max);
        let finger_bottom = m.uv[32 * 19..].iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
        assert!(finger_bottom > arm_top + 0.5 * ISLAND_GAP, "{arm_top} {finger_bottom}");
        // Round arm at the wrist, flat palm.
        assert_eq!(arm_section(-60.0), (12.0, 12.0));
        assert_eq!(arm_section(-10.0), (22.0, 8.0));
    }
}
