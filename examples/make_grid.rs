//! Writes the height-field grid of issue 19 as a Wavefront OBJ: `n` x `n` quads over the unit
//! square, two triangles each (`2 n^2` triangles, `(n + 1)^2` shared vertices): the vertices of
//! `raylume::scene::grid` (the benches' grids). The sizes the issue measures: 224 (100,352
//! triangles), 707 (999,698), 1224 (2,996,352).
//!
//! ```text
//! cargo run --release --example make_grid -- 1224 grid-3m.obj
//! cargo run --release --example render -- grid-3m.obj --backend cpu --size 128x128 --spp 4 --stats
//! ```
//!
//! The file is byte-for-byte deterministic (vertices printed with 6 decimals; ~110 MB at 1224).
//! `tools/large/` measures raylume and Mitsuba 3 loading and rendering it.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::process::ExitCode;

use raylume::scene::grid;

fn write_grid(n: usize, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        out,
        "# raylume make_grid: {n} x {n} quads, {} triangles",
        2 * n * n
    )?;
    for j in 0..=n {
        for i in 0..=n {
            let p = grid::vertex(n, i, j);
            writeln!(out, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z)?;
        }
    }
    // Vertex (i, j) is number j (n + 1) + i + 1 (OBJ counts from 1). The quad's triangles are
    // (i,j) (i+1,j) (i+1,j+1) and (i,j) (i+1,j+1) (i,j+1), as the bench's grid.
    let v = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            writeln!(out, "f {a} {b} {c}")?;
            writeln!(out, "f {a} {c} {d}")?;
        }
    }
    out.flush()
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (n, path) = match args.as_slice() {
        [n, path] => match n.parse::<usize>() {
            Ok(n) if (1..=20_000).contains(&n) => (n, path),
            _ => {
                eprintln!("make_grid: N must be a whole number from 1 to 20000, not `{n}`");
                return ExitCode::from(2);
            }
        },
        _ => {
            eprintln!(
                "usage: make_grid N OUT.obj   (2 N^2 triangles; 224, 707, 1224: issue 19's sizes)"
            );
            return ExitCode::from(2);
        }
    };
    let result = File::create(path).and_then(|f| write_grid(n, &mut BufWriter::new(f)));
    match result {
        Ok(()) => {
            println!(
                "{path}: {} triangles, {} vertices",
                2 * n * n,
                (n + 1) * (n + 1)
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("make_grid: cannot write {path}: {e}");
            ExitCode::FAILURE
        }
    }
}
