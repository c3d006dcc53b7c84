//! The viewer layout sent with every recording and live stream (Rerun's blueprint API): per
//! patch a 3D view of its layers (with the body and anchors where it has them) over its energy,
//! residual and Newton iterations; first, per shared body, a 3D view of the body with every
//! patch on it; beside them one plot of the stage timings the scene runs, and for remeshed
//! layers their material-space view, and the colour legend.

use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial3DView, Tabs, TextDocumentView, TimeSeriesView, Vertical,
};
use skinsim::scene::BuiltScene;

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
            let view = match p.body {
                Some(bi) => Spatial3DView::new(p.name.clone()).with_origin("/patches").with_contents([
                    format!("+ /patches/{}/**", p.name),
                    format!("+ /patches/{}/**", scene.bodies[bi].name),
                ]),
                None => Spatial3DView::new(p.name.clone()).with_origin(format!("/patches/{}", p.name)),
            };
            let series = ["energy", "residual", "newton_iterations"].map(|s| {
                TimeSeriesView::new(format!("{} {}", p.name, s.replace('_', " ")))
                    .with_origin(format!("/stats/{}/{s}", p.name))
                    .into()
            });
            let column = Vertical::new([view.into(), Horizontal::new(series).into()]).with_row_shares([3.0, 1.0]);
            column.with_name(p.name.clone()).into()
        }))
        .collect();
    let timings = TimeSeriesView::new("stage timings (ms)")
        .with_origin("/timings")
        .with_contents(stages.iter().map(|s| format!("+ /timings/{s}")));
    let legend = TextDocumentView::new("colour legend").with_origin(format!("/{}", skinsim_systems::log::LEGEND));
    let mut side: Vec<ContainerLike> = vec![timings.into(), legend.into()];
    for p in &scene.patches {
        for l in p.layers.iter().filter(|l| l.remesh.is_some()) {
            let origin = format!("/material/{}/{}", p.name, l.name);
            side.push(Spatial3DView::new(format!("{} {} material space", p.name, l.name)).with_origin(origin).into());
        }
    }
    let root = Horizontal::new([Tabs::new(patches).into(), Vertical::new(side).into()]).with_column_shares([2.0, 1.0]);
    Blueprint::new(root).with_auto_views(false)
}
