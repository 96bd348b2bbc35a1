//! `render`: path-trace a scene into a `.pds` dump (and optionally a
//! reference EXR). Parses arguments and calls the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};
use pathdensity::dump::Order;
use pathdensity::io::exr;
use pathdensity::io::guard::{self, Inputs};
use pathdensity::recon::{Image, ReconFilter};
use pathdensity_render::sampler::independent_seed;
use pathdensity_render::{
    AUX_SPP, RenderSettings, SceneName, render_aux, render_dump, render_reference,
};

use pathdensity::cli::Bar;

#[derive(Clone, Copy, ValueEnum)]
enum OrderArg {
    Pixel,
    Pass,
}

#[derive(Clone, Copy, ValueEnum)]
enum Recon {
    Box,
    Gaussian,
}

/// Path-trace a scene into a pathdensity sample dump.
#[derive(Parser)]
#[command(name = "render", version)]
struct Cli {
    /// glossy-room, diffuse-room, two-lights, indirect-room, sky or moving.
    #[arg(long)]
    scene: SceneName,
    #[arg(long, default_value_t = 128)]
    width: u32,
    #[arg(long, default_value_t = 128)]
    height: u32,
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Frames (default: 8 for `moving`, 1 otherwise).
    #[arg(long)]
    frames: Option<u32>,
    #[arg(long, value_enum, default_value_t = OrderArg::Pixel)]
    order: OrderArg,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The dump to write.
    #[arg(short, long)]
    out: PathBuf,
    /// Samples per pixel of the reference (needs --reference-out).
    #[arg(long, requires = "reference_out")]
    reference_spp: Option<u32>,
    /// The reference EXR (an animation writes REF_0000.exr, … beside it).
    #[arg(long, requires = "reference_spp")]
    reference_out: Option<PathBuf>,
    /// The first-hit albedo EXR, a denoiser's auxiliary image (`filter
    /// --albedo`; an animation writes A_0000.exr, … beside it).
    #[arg(long)]
    albedo_out: Option<PathBuf>,
    /// The first-hit shading normal EXR (`filter --normal`).
    #[arg(long)]
    normal_out: Option<PathBuf>,
    /// Camera rays per pixel of the albedo and normal.
    #[arg(long, default_value_t = AUX_SPP)]
    aux_spp: u32,
    /// The reference's reconstruction filter: use the one you filter with.
    #[arg(long, value_enum, default_value_t = Recon::Box)]
    recon: Recon,
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0, value_parser = pathdensity::cli::threads)]
    threads: usize,
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let pool = pathdensity::pipeline::thread_pool(cli.threads)?;
    let frames = cli.frames.unwrap_or(cli.scene.default_frames());
    let scene = cli.scene.build(frames);
    let mut st = RenderSettings {
        width: cli.width,
        height: cli.height,
        frames,
        spp: cli.spp,
        order: match cli.order {
            OrderArg::Pixel => Order::PixelMajor,
            OrderArg::Pass => Order::PassMajor,
        },
        seed: cli.seed,
    };
    // Every output is checked before the render: each may replace only a
    // file of its own kind (an EXR only if pathdensity wrote it), and no
    // two outputs are one file.
    let images = [
        ("reference", &cli.reference_out),
        ("albedo", &cli.albedo_out),
        ("normal", &cli.normal_out),
    ];
    let mut taken = vec![("dump", cli.out.clone())];
    for (name, path) in images {
        let Some(path) = path else { continue };
        for p in exr::reference_files(path, frames as usize) {
            if let Some((other, _)) = taken.iter().find(|(_, q)| *q == p) {
                anyhow::bail!("{}: is both the {other} and the {name}", p.display());
            }
            Inputs::default().check_file(&p, exr::written_by_us)?;
            taken.push((name, p));
        }
    }
    Inputs::default().check_file(&cli.out, guard::looks_like_dump)?;
    let t = Instant::now();
    let h = pool.install(|| render_dump(&scene, &st, &cli.out, &Bar::new("render")))?;
    let secs = t.elapsed().as_secs_f64();
    println!(
        "{}: {} {}×{}×{} at {} spp, {} samples in {:.2} s ({:.2} M samples/s)",
        cli.out.display(),
        h.scene,
        h.width,
        h.height,
        h.frames,
        h.spp,
        h.sample_count,
        secs,
        h.sample_count as f64 / secs / 1e6
    );
    if cli.albedo_out.is_some() || cli.normal_out.is_some() {
        let aux = RenderSettings {
            spp: cli.aux_spp,
            ..st.clone()
        };
        let t = Instant::now();
        let [albedo, normal] = pool.install(|| render_aux(&scene, &aux, &Bar::new("albedo")))?;
        for (path, img) in [(&cli.albedo_out, &albedo), (&cli.normal_out, &normal)] {
            if let Some(path) = path {
                let written = write_exr(path, img)?;
                println!(
                    "{}: at {} spp in {:.2} s",
                    written.display(),
                    cli.aux_spp,
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
    if let (Some(spp), Some(path)) = (cli.reference_spp, cli.reference_out) {
        st.spp = spp;
        st.seed = independent_seed(cli.seed);
        let filter = match cli.recon {
            Recon::Box => ReconFilter::Box,
            Recon::Gaussian => ReconFilter::gaussian(),
        };
        let t = Instant::now();
        let img = pool.install(|| render_reference(&scene, &st, filter, &Bar::new("reference")))?;
        let written = write_exr(&path, &img)?;
        println!(
            "{}: reference at {spp} spp in {:.2} s",
            written.display(),
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// `img` written as the EXR `path` names (an animation's frames as
/// STEM_0000.exr, … beside it); the first file written.
fn write_exr(path: &Path, img: &Image) -> anyhow::Result<PathBuf> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into());
    let names = exr::write_image(dir, &stem, img)?;
    Ok(dir.join(&names[0]))
}

fn main() -> ExitCode {
    pathdensity::cli::run_main("render", || run(Cli::parse()))
}
