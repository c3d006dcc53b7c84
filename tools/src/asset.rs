//! `skinsim asset`: the procedural assets of the character scenes (issue 24), written as OBJ
//! files with texture coordinates, so that the scenes load them as a user's own meshes would be.

use std::io::Write;
use std::path::Path;

use skinsim::mesh::hand::{hand, HandShape};

/// Writes `<out>/<name>.obj`: the hand-like body (`mesh::hand`), lengths and UVs in mm, one
/// `o` object per tube. Returns the vertex and face counts.
pub fn write_hand(out: &Path, name: &str, shape: HandShape) -> std::io::Result<(usize, usize)> {
    std::fs::create_dir_all(out)?;
    let m = hand(shape);
    let path = out.join(format!("{name}.obj"));
    let mut w = std::io::BufWriter::new(std::fs::File::create(&path)?);
    writeln!(
        w,
        "# skinsim asset hand (mm): arm and palm, two fingers; finger cells {:?}, arm cells {:?}",
        shape.finger_cells, shape.arm_cells
    )?;
    writeln!(w, "# made by: skinsim asset hand --out <dir> (tools/src/asset.rs); UVs: u = x, v = arc length")?;
    for p in &m.rest {
        writeln!(w, "v {:.5} {:.5} {:.5}", p.x, p.y, p.z)?;
    }
    for t in &m.uv {
        writeln!(w, "vt {:.5} {:.5}", t.x, t.y)?;
    }
    let arm = 2 * shape.arm_cells.0 as usize * shape.arm_cells.1 as usize;
    let finger = 2 * shape.finger_cells.0 as usize * shape.finger_cells.1 as usize;
    for (i, f) in m.faces.iter().enumerate() {
        match i {
            0 => writeln!(w, "o arm")?,
            _ if i == arm => writeln!(w, "o finger_a")?,
            _ if i == arm + finger => writeln!(w, "o finger_b")?,
            _ => {}
        }
        let [a, b, c] = f.map(|v| v + 1);
        writeln!(w, "f {a}/{a} {b}/{b} {c}/{c}")?;
    }
    w.flush()?;
    Ok((m.rest.len(), m.faces.len()))
}
