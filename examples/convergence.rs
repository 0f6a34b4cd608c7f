//! Do ARPA and RTPM converge to the same image? Renders the embedded default scene with
//! both methods on the CPU backend and prints, at doubling iteration counts, the relative
//! MSE between the two running estimates, `mean((a − b)² / (b² + 0.01))` over pixels and
//! channels, and each method's relMSE against its own final image.
//!
//! ```text
//! cargo run --release --example convergence -- [RESOLUTION] [PHOTONS] [ITERATIONS]
//! ```
//! Defaults: 128 (square), 100000 photons per iteration, 256 iterations.

use arpa::core::render::tracer::{Image, Method, RenderSettings, Tracer};
use arpa::cpu::CpuTracer;
use arpa::default_scene::default_scene;
use std::time::Instant;

fn rel_mse(a: &Image, b: &Image) -> f64 {
    let mut sum = 0.0;
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (x[c] as f64, y[c] as f64);
            sum += (x - y) * (x - y) / (y * y + 0.01);
        }
    }
    sum / (3 * a.pixels.len()) as f64
}

fn main() -> anyhow::Result<()> {
    let args: Vec<u32> = std::env::args().skip(1).map(|a| a.parse()).collect::<Result<_, _>>()?;
    let resolution = args.first().copied().unwrap_or(128);
    let photons = args.get(1).copied().unwrap_or(100_000);
    let iterations = args.get(2).copied().unwrap_or(256);
    let mut scene = default_scene();
    scene.camera.width = resolution;
    scene.camera.height = resolution;
    let mut tracers = vec![];
    for method in [Method::Arpa, Method::Rtpm] {
        let settings = RenderSettings { method, photons_per_iteration: photons, ..RenderSettings::default() };
        let mut t = CpuTracer::new()?;
        t.upload_scene(&scene, &settings)?;
        tracers.push(t);
    }
    println!("default scene {resolution}x{resolution}, {photons} photons/iteration");
    println!("{:>10} {:>22} {:>10} {:>10}", "iterations", "relMSE(arpa, rtpm)", "arpa s", "rtpm s");
    let mut checkpoints = vec![];
    let mut times = [0.0f64; 2];
    let mut next = 1;
    for it in 1..=iterations {
        for (k, t) in tracers.iter_mut().enumerate() {
            let start = Instant::now();
            t.iterate()?;
            times[k] += start.elapsed().as_secs_f64();
        }
        if it == next || it == iterations {
            let (a, r) = (tracers[0].read_image()?, tracers[1].read_image()?);
            println!("{it:>10} {:>22.6} {:>10.1} {:>10.1}", rel_mse(&a, &r), times[0], times[1]);
            checkpoints.push((it, a, r));
            next *= 2;
        }
    }
    let (_, final_a, final_r) = checkpoints.last().cloned().expect("at least one checkpoint");
    println!("\nrelMSE of each method against its own final image:");
    println!("{:>10} {:>12} {:>12}", "iterations", "arpa", "rtpm");
    for (it, a, r) in &checkpoints {
        println!("{it:>10} {:>12.6} {:>12.6}", rel_mse(a, &final_a), rel_mse(r, &final_r));
    }
    Ok(())
}
