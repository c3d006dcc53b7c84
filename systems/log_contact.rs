//! Log (issue 64): each patch's active contact pairs as line segments between their closest
//! points, coloured by how close they are (red: at the thickness, yellow: at the barrier's
//! reach), and per patch the contact figures of the frame: active pairs, the smallest distance
//! over the thickness, the barrier stiffness, CCD cuts and re-analyses. LK14 kernels released
//! where skin touches skin are magenta segments from the skin's average to the body point.

use bevy_ecs::prelude::*;
use skinsim::contact::{distance::closest_points, gather};
use skinsim::model::*;
use skinsim::solve::PackedPatch;

use crate::log::RerunSink;

pub fn log_contact(
    sink: Res<RerunSink>,
    report: Res<FrameReport>,
    patches: Query<(&Patch, &PackedPatch), With<Contact>>,
) {
    let rec = &sink.0;
    for (patch, packed) in &patches {
        let x = &packed.state.x;
        let (mut segments, mut colours) = (Vec::new(), Vec::new());
        for p in &packed.elements.contacts.pairs {
            let y = gather(x, &p.v);
            let d2 = p.squared_distance(&y);
            if !p.barrier.active(d2) {
                continue;
            }
            let (a, b) = closest_points(p.kind, &y);
            segments.push([a.map(|c| c as f32), b.map(|c| c as f32)]);
            // 0 at the offset (red), 1 at the reach (yellow)
            let t = ((d2.sqrt() - p.barrier.offset) / p.barrier.reach).clamp(0.0, 1.0);
            colours.push(rerun::Color::from_rgb(255, (220.0 * t) as u8, 0));
        }
        let base = format!("patches/{}/contact", patch.name);
        let _ = rec.log(format!("{base}/pairs"), &rerun::LineStrips3D::new(segments).with_colors(colours));
        // Released kernels (`solve::release`): from the skin's average to the body point the
        // kernel would hold it to.
        let released = packed.contact.as_ref().map_or(&[][..], |c| &c.released[..]);
        let kernels = &packed.constraints.kernels;
        let gaps: Vec<[[f32; 3]; 2]> = kernels
            .iter()
            .zip(released)
            .filter(|(_, r)| **r)
            .map(|(k, _)| {
                let body = k.lower_point(x);
                [(body + k.value(x)).as_vec3().to_array(), body.as_vec3().to_array()]
            })
            .collect();
        let _ = rec.log(
            format!("{base}/released_kernels"),
            &rerun::LineStrips3D::new(gaps).with_colors([rerun::Color::from_rgb(230, 0, 230)]),
        );
        let Some(c) = report.patches.iter().find(|r| r.name == patch.name).and_then(|r| r.outcome.contact) else {
            continue;
        };
        let stats = format!("stats/{}/contact", patch.name);
        let _ = rec.log(format!("{stats}/active_pairs"), &rerun::Scalars::new([c.active_pairs as f64]));
        if c.min_distance_ratio.is_finite() {
            let _ = rec.log(format!("{stats}/min_distance_ratio"), &rerun::Scalars::new([c.min_distance_ratio]));
        }
        let _ = rec.log(format!("{stats}/stiffness"), &rerun::Scalars::new([c.stiffness]));
        let _ = rec.log(format!("{stats}/ccd_cuts"), &rerun::Scalars::new([c.ccd_cuts as f64]));
        let _ = rec.log(format!("{stats}/reanalyses"), &rerun::Scalars::new([c.reanalyses as f64]));
        if c.released_kernels > 0 {
            let _ = rec.log(format!("{stats}/released_kernels"), &rerun::Scalars::new([c.released_kernels as f64]));
        }
        if c.friction_pairs > 0 {
            let _ = rec.log(format!("{stats}/friction_pairs"), &rerun::Scalars::new([c.friction_pairs as f64]));
            let _ = rec.log(format!("{stats}/slip"), &rerun::Scalars::new([c.slip]));
        }
    }
}
