//! The stage as text (`.usda`, Pixar's documented format), written from the spool.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::{Attr, Prim, UsdStage, ATTRIBUTES};

pub(super) fn write(stage: &UsdStage, path: &Path) -> std::io::Result<()> {
    let mut w = BufWriter::new(File::create(path)?);
    let (first, last) = stage.frames.unwrap_or((0, 0));
    writeln!(w, "#usda 1.0\n(")?;
    writeln!(w, "    defaultPrim = \"skinsim\"\n    doc = \"{}\"", escape(&stage.doc))?;
    writeln!(w, "    metersPerUnit = 1\n    upAxis = \"Z\"")?;
    writeln!(w, "    startTimeCode = {first}\n    endTimeCode = {last}")?;
    writeln!(w, "    timeCodesPerSecond = {0}\n    framesPerSecond = {0}\n)\n", stage.frames_per_second)?;
    writeln!(w, "def Xform \"skinsim\"\n{{")?;
    for (patch, prims) in stage.patches() {
        let name = &prims[0].1.names.0;
        writeln!(
            w,
            "    def Xform \"{name}\" (\n        customData = {{ string name = \"{}\" }}\n    )\n    {{",
            escape(patch)
        )?;
        for (i, prim) in prims {
            write_mesh(stage, &mut w, i, prim)?;
        }
        writeln!(w, "    }}")?;
    }
    writeln!(w, "}}")?;
    w.flush()
}

fn write_mesh(stage: &UsdStage, w: &mut impl Write, i: usize, prim: &Prim) -> std::io::Result<()> {
    let name = &prim.names.1;
    let st = match prim.asset_uv {
        true => "; string st = \"asset\"".to_string(),
        false => format!("; string st = \"material\"; double stMetres = {}", stage.options.st_unit),
    };
    writeln!(
        w,
        "        def Mesh \"{name}\" (\n            customData = {{ string name = \"{}\"{st} }}\n        )\n        {{",
        escape(&prim.layer),
    )?;
    writeln!(w, "            uniform token orientation = \"rightHanded\"")?;
    writeln!(w, "            uniform token subdivisionScheme = \"none\"")?;
    if stage.options.double_sided {
        writeln!(w, "            uniform bool doubleSided = 1")?;
    }
    if let Some((tris, uv)) = &prim.fixed {
        write!(w, "            int[] faceVertexCounts = [")?;
        list(w, tris, |w, _| write!(w, "3"))?;
        write!(w, "\n            int[] faceVertexIndices = [")?;
        list(w, tris, |w, t| write!(w, "{}, {}, {}", t[0], t[1], t[2]))?;
        write!(w, "\n            texCoord2f[] primvars:st = [")?;
        list(w, uv, |w, t| write!(w, "({}, {})", t.x as f32, t.y as f32))?;
        writeln!(w, " (\n                interpolation = \"vertex\"\n            )")?;
    }
    for &a in ATTRIBUTES.iter().take(prim.spools.len()) {
        let (ty, attr, _) = a.names();
        if a.per_vertex() {
            writeln!(w, "            {ty} {attr} (\n                interpolation = \"vertex\"\n            )")?;
        }
        writeln!(w, "            {ty} {attr}.timeSamples = {{")?;
        let mut r = stage.reader(i, a)?;
        let width = match a {
            Attr::St => 2,
            Attr::Counts => 1,
            _ => 3,
        };
        // (integers flat, "0, 1, 2"; vectors as tuples, "(0, 0, 1)")
        if a.is_int() {
            while let Some((frame, v)) = r.next_ints()? {
                sample(w, frame, &v, width, false)?;
            }
        } else {
            while let Some((frame, v)) = r.next_floats()? {
                sample(w, frame, &v, width, true)?;
            }
        }
        writeln!(w, "            }}")?;
    }
    writeln!(w, "        }}")
}

/// One time sample, "        <frame>: [items],": `values` in groups of `width`, each group in
/// parentheses when `tuples`.
fn sample<T: std::fmt::Display>(
    w: &mut impl Write,
    frame: u32,
    values: &[T],
    width: usize,
    tuples: bool,
) -> std::io::Result<()> {
    write!(w, "        {frame}: [")?;
    list(w, &values.chunks(width).collect::<Vec<_>>(), |w, c| {
        let s: Vec<String> = c.iter().map(|x| x.to_string()).collect();
        match tuples {
            true => write!(w, "({})", s.join(", ")),
            false => write!(w, "{}", s.join(", ")),
        }
    })?;
    writeln!(w, ",")
}

/// Writes the items of `items` comma-separated, then "]".
fn list<T, W: Write>(
    w: &mut W,
    items: &[T],
    mut item: impl FnMut(&mut W, &T) -> std::io::Result<()>,
) -> std::io::Result<()> {
    for (i, x) in items.iter().enumerate() {
        if i > 0 {
            write!(w, ", ")?;
        }
        item(w, x)?;
    }
    write!(w, "]")
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}
