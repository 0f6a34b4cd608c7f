//! Region means of a render against a reference, to tell bias from noise: a noisy but
//! unbiased render has region means close to the reference's even where per-pixel errors
//! are large.
//!
//! ```text
//! cargo run --release --example region_means -- REF.exr TEST.exr [name:r0-r1,c0-c1 ...] [--grid N]
//! ```
//!
//! Rows `r0..r1` and columns `c0..c1` are pixel ranges (end exclusive), as in the scenes
//! README. Each region prints the mean linear RGB of both images and their ratio
//! (TEST/REF, per channel and of the channel average). `--grid N` also prints the ratio
//! of the channel averages over an N×N grid of blocks covering the image. The first line
//! gives relMSE, SSIM and FLIP of TEST against REF (`arpa::metrics`, as `--reference`).

use anyhow::{Context, bail};
use arpa::image_io::read_exr;
use std::path::Path;

fn parse_range(s: &str) -> anyhow::Result<(usize, usize)> {
    let (a, b) = s.split_once('-').with_context(|| format!("range '{s}' must be A-B"))?;
    Ok((a.trim().parse()?, b.trim().parse()?))
}

fn mean(img: &arpa::core::render::tracer::Image, rows: (usize, usize), cols: (usize, usize)) -> [f64; 3] {
    let mut s = [0.0f64; 3];
    let mut n = 0usize;
    for r in rows.0..rows.1.min(img.height as usize) {
        for c in cols.0..cols.1.min(img.width as usize) {
            let p = img.pixels[r * img.width as usize + c];
            s[0] += p.x as f64;
            s[1] += p.y as f64;
            s[2] += p.z as f64;
            n += 1;
        }
    }
    s.map(|v| v / n.max(1) as f64)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        bail!("usage: region_means REF.exr TEST.exr [name:r0-r1,c0-c1 ...] [--grid N]");
    }
    let reference = read_exr(Path::new(&args[0]))?;
    let test = read_exr(Path::new(&args[1]))?;
    if (reference.width, reference.height) != (test.width, test.height) {
        bail!("sizes differ: {}x{} vs {}x{}", reference.width, reference.height, test.width, test.height);
    }
    let (w, h) = (reference.width as usize, reference.height as usize);
    let mut regions = vec![("whole".to_string(), (0, h), (0, w))];
    let mut grid = 0usize;
    let mut it = args[2..].iter();
    while let Some(a) = it.next() {
        if a == "--grid" {
            grid = it.next().context("--grid needs N")?.parse()?;
            continue;
        }
        let (name, spec) = a.split_once(':').with_context(|| format!("region '{a}' must be name:r0-r1,c0-c1"))?;
        let (rows, cols) = spec.split_once(',').with_context(|| format!("region '{a}' must be name:r0-r1,c0-c1"))?;
        regions.push((name.to_string(), parse_range(rows)?, parse_range(cols)?));
    }
    let m = arpa::metrics::compare_images(&test, &reference)?;
    println!("relMSE {:.4e}  SSIM {:.4}  FLIP {:.4}", m.rel_mse, m.ssim, m.flip);
    println!("{:<16} {:>30} {:>30} {:>24} {:>7}", "region", "REF mean RGB", "TEST mean RGB", "TEST/REF RGB", "avg");
    for (name, rows, cols) in &regions {
        let a = mean(&reference, *rows, *cols);
        let b = mean(&test, *rows, *cols);
        let ratio = |i: usize| if a[i] > 0.0 { b[i] / a[i] } else { f64::NAN };
        let avg = (b[0] + b[1] + b[2]) / (a[0] + a[1] + a[2]);
        println!(
            "{name:<16} {:>9.5} {:>9.5} {:>9.5}  {:>9.5} {:>9.5} {:>9.5}  {:>7.3} {:>7.3} {:>7.3} {avg:>7.3}",
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2],
            ratio(0),
            ratio(1),
            ratio(2)
        );
    }
    if grid > 0 {
        println!("TEST/REF of the channel average over a {grid}x{grid} grid (REF mean in brackets):");
        for gr in 0..grid {
            let rows = (gr * h / grid, (gr + 1) * h / grid);
            let mut line = String::new();
            for gc in 0..grid {
                let cols = (gc * w / grid, (gc + 1) * w / grid);
                let a = mean(&reference, rows, cols);
                let b = mean(&test, rows, cols);
                let (sa, sb) = (a.iter().sum::<f64>() / 3.0, b.iter().sum::<f64>() / 3.0);
                line += &format!(" {:>5.2}[{:.3}]", if sa > 0.0 { sb / sa } else { f64::NAN }, sa);
            }
            println!("{line}");
        }
    }
    Ok(())
}
