//! The viewer layout sent with every recording and live stream (Rerun's blueprint API): per
//! patch a tab with a 3D view of its own layers only (so that the view frames the patch, not the
//! body it sits on) over tabs of its energy (J), log10 residual, Newton iterations and, with
//! anchors, the anchor jumps (m); first, per shared body, a 3D view of the body with every patch
//! on it; beside them one plot of the stage timings the scene runs (from frame 2: frame 1's
//! set-up would flatten the rest), the colour legend, the anchors' legend where there are
//! anchors, the colour bar, and for remeshed layers their material-space view.

use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial2DView, Spatial3DView, Tabs, TextDocumentView, TimeSeriesView,
    Vertical,
};
use skinsim::scene::BuiltScene;

/// The per-patch plots: (the entity under /stats/<patch>, the plot's title).
pub const PATCH_PLOTS: [(&str, &str); 3] = [
    ("energy", "energy (J)"),
    ("log10_residual", "log10 residual (relative)"),
    ("newton_iterations", "Newton iterations"),
];

/// The layout for `scene`; `stages`: the keys of the stages that ran (a stage that never runs
/// gets no plot).
pub fn layout(scene: &BuiltScene, stages: &[String]) -> Blueprint {
    // A shared body's tab: the body and every patch on it, as the character is seen.
    let bodies = scene.bodies.iter().enumerate().map(|(bi, b)| {
        let on: Vec<String> = std::iter::once(&b.name)
            .chain(scene.patches.iter().filter(|p| p.body == Some(bi)).map(|p| &p.name))
            .map(|n| format!("+ /patches/{n}/**"))
            .collect();
        Spatial3DView::new(b.name.clone()).with_origin("/patches").with_contents(on).into()
    });
    let patches: Vec<ContainerLike> = bodies
        .chain(scene.patches.iter().map(|p| {
            let view = Spatial3DView::new(p.name.clone()).with_origin(format!("/patches/{}", p.name));
            let mut plots: Vec<ContainerLike> = PATCH_PLOTS
                .iter()
                .map(|(entity, title)| {
                    TimeSeriesView::new(format!("{} {title}", p.name))
                        .with_origin(format!("/stats/{}/{entity}", p.name))
                        .into()
                })
                .collect();
            if p.anchors.is_some() {
                let anchors = TimeSeriesView::new(format!("{} anchor jumps (m)", p.name))
                    .with_origin(format!("/stats/{}/anchors", p.name));
                plots.push(anchors.into());
            }
            let column = Vertical::new([view.into(), Tabs::new(plots).into()]).with_row_shares([3.0, 1.4]);
            column.with_name(p.name.clone()).into()
        }))
        .collect();
    let timings = TimeSeriesView::new("stage timings (ms), from frame 2")
        .with_origin("/timings")
        .with_contents(stages.iter().map(|s| format!("+ /timings/{s}")));
    let legend = TextDocumentView::new("colour legend").with_origin(format!("/{}", skinsim_systems::log::LEGEND));
    let bar = Spatial2DView::new("colour bar: red -scale, white 0, blue +scale (the legend gives the scale)")
        .with_origin(format!("/{}", skinsim_systems::log::COLOUR_BAR));
    let mut side: Vec<ContainerLike> = vec![timings.into(), legend.into(), bar.into()];
    for p in scene.patches.iter().filter(|p| p.anchors.is_some()) {
        let skin = &p.layers[p.anchors.as_ref().expect("filtered").skin].name;
        let origin = format!("/{}/{}/{skin}", skinsim_systems::log_anchors::ANCHOR_LEGEND, p.name);
        side.push(TextDocumentView::new(format!("{} anchors", p.name)).with_origin(origin).into());
    }
    for p in &scene.patches {
        for l in p.layers.iter().filter(|l| l.remesh.is_some()) {
            let origin = format!("/material/{}/{}", p.name, l.name);
            side.push(Spatial3DView::new(format!("{} {} material space", p.name, l.name)).with_origin(origin).into());
        }
    }
    let root = Horizontal::new([Tabs::new(patches).into(), Vertical::new(side).into()]).with_column_shares([2.0, 1.0]);
    Blueprint::new(root).with_auto_views(false)
}
