//! Log (KCK18): each skin layer's anchors as small points coloured by how far they walked this
//! frame, on a palette of their own (dark violet: not at all, yellow: the frame's longest walk;
//! the strain palette means something else), with a legend of their own (`ANCHOR_LEGEND`), the
//! anchor springs as line segments, and per patch the largest anchor jump and its excess over the
//! step (the jump across a fold).

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::model::*;

use crate::log::RerunSink;

/// An anchor's dot, in UI points: small, so that the skin under the anchors stays visible.
const ANCHOR_DOT: f32 = 0.8;

/// The entity of the anchors' colour legend (a text document).
pub const ANCHOR_LEGEND: &str = "anchor_legend";

/// The anchors' palette at t in [0, 1]: dark violet, teal, yellow (viridis's ends and middle).
fn walk_colour(t: f64) -> rerun::Color {
    const STOPS: [[f64; 3]; 3] = [[68.0, 1.0, 84.0], [33.0, 145.0, 140.0], [253.0, 231.0, 37.0]];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let (i, f) = if t < 0.5 { (0, 2.0 * t) } else { (1, 2.0 * t - 1.0) };
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    rerun::Color::from_rgb(c(0), c(1), c(2))
}

pub fn log_anchors(
    sink: Res<RerunSink>,
    patches: Query<(&Patch, Option<&AnchorReport>)>,
    skins: Query<(&Layer, &LayerAnchors, &LayerOf)>,
    anchors: Query<(&Anchor, &AnchorState)>,
    positions: Query<&Position>,
) {
    let rec = &sink.0;
    let at = |v: Entity| positions.get(v).map_or(DVec3::NAN, |p| p.0);
    let f3 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
    for (layer, list, patch) in &skins {
        let Ok((patch, report)) = patches.get(patch.0) else { continue };
        let states: Vec<(&Anchor, &AnchorState)> =
            list.entities().iter().filter_map(|&a| anchors.get(a).ok()).collect();
        let longest = states.iter().fold(0.0f64, |m, (_, s)| m.max(s.walked)).max(f64::MIN_POSITIVE);
        let colours = states.iter().map(|(_, s)| walk_colour(s.walked / longest));
        let legend = format!(
            "### Anchors of {}/{}\nDots coloured by how far each anchor walked over the body this frame: dark \
             violet not at all, teal half, yellow the frame's longest walk ({:.3} mm). Lines: the anchor springs.",
            patch.name,
            layer.name,
            1e3 * if longest > f64::MIN_POSITIVE { longest } else { 0.0 }
        );
        let _ = rec
            .log(format!("{ANCHOR_LEGEND}/{}/{}", patch.name, layer.name), &rerun::TextDocument::from_markdown(legend));
        let base = format!("patches/{}/{}/anchors", patch.name, layer.name);
        let points = states.iter().map(|(_, s)| f3(s.position));
        // Screen-sized dots: anchors sit at every vertex and face centre, so any radius in metres
        // either hides the skin when zoomed in or vanishes when zoomed out.
        let radius = rerun::components::Radius::new_ui_points(ANCHOR_DOT);
        let _ =
            rec.log(format!("{base}/points"), &rerun::Points3D::new(points).with_colors(colours).with_radii([radius]));
        let springs = states.iter().map(|(a, s)| {
            let skin = match a.skin {
                SkinPoint::Vertex(v) => at(v),
                SkinPoint::Face(f) => f.iter().map(|&v| at(v)).sum::<DVec3>() / 3.0,
            };
            [f3(s.position), f3(skin)]
        });
        let _ = rec.log(format!("{base}/springs"), &rerun::LineStrips3D::new(springs));
        if let Some(r) = report {
            let stats = format!("stats/{}/anchors", patch.name);
            let _ = rec.log(format!("{stats}/max_jump"), &rerun::Scalars::new([r.max_jump]));
            let _ = rec.log(format!("{stats}/max_excess"), &rerun::Scalars::new([r.max_excess]));
        }
    }
}
