//! The one-command demo: render the glossy room, render its reference,
//! filter the dump and print the summary. No arguments needed.

use std::path::{Path, PathBuf};

use anyhow::Context;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use pathdensity::commands::filter;
use pathdensity::config::MethodSet;
use pathdensity::dump::Order;
use pathdensity::io::exr;
use pathdensity::io::guard::{self, Inputs};
use pathdensity::recon::ReconFilter;
use pathdensity_render::sampler::independent_seed;
use pathdensity_render::{
    AUX_SPP, RenderSettings, SceneName, render_aux, render_dump, render_reference,
};

use pathdensity::cli::Bar;

/// Render a scene, its reference, and filter it.
#[derive(Parser)]
#[command(name = "demo", version)]
struct Cli {
    /// glossy-room, diffuse-room, two-lights, indirect-room, sky or moving.
    #[arg(long, default_value_t = SceneName::GlossyRoom)]
    scene: SceneName,
    #[arg(short, long, default_value = "out/demo")]
    out: PathBuf,
    /// Film width and height.
    #[arg(long, default_value_t = 128)]
    size: u32,
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[arg(long, default_value_t = 1024)]
    reference_spp: u32,
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let name = cli.scene.as_str();
    let frames = cli.scene.default_frames();
    let ref_name = format!("{name}_ref");
    let aux_names = [format!("{name}_albedo"), format!("{name}_normal")];
    let mut ours = vec![format!("{name}.pds"), "filtered".to_string()];
    for stem in std::iter::once(&ref_name).chain(&aux_names) {
        for p in exr::reference_files(&cli.out.join(format!("{stem}.exr")), frames as usize) {
            ours.extend(p.file_name().map(|n| n.to_string_lossy().into_owned()));
        }
    }
    claim(&cli.out, &ours)?;
    let scene = cli.scene.build(frames);
    let mut st = RenderSettings {
        width: cli.size,
        height: cli.size,
        frames,
        spp: cli.spp,
        order: Order::PixelMajor,
        seed: cli.seed,
    };
    let dump = cli.out.join(format!("{name}.pds"));
    let t = Instant::now();
    render_dump(&scene, &st, &dump, &Bar::new("render"))?;
    println!(
        "rendered {} ({}×{}, {} spp) in {:.2} s",
        dump.display(),
        st.width,
        st.height,
        st.spp,
        t.elapsed().as_secs_f64()
    );
    // The first-hit albedo and normal, as a renderer's denoising passes
    // give them: OIDN's auxiliary images and statmc's guide.
    let aux = RenderSettings {
        spp: AUX_SPP,
        ..st.clone()
    };
    let [albedo, normal] = render_aux(&scene, &aux, &Bar::new("albedo"))?;
    exr::write_image(&cli.out, &aux_names[0], &albedo)?;
    exr::write_image(&cli.out, &aux_names[1], &normal)?;
    st.spp = cli.reference_spp;
    st.seed = independent_seed(cli.seed);
    let t = Instant::now();
    let reference = render_reference(&scene, &st, ReconFilter::Box, &Bar::new("reference"))?;
    exr::write_image(&cli.out, &ref_name, &reference)?;
    println!(
        "rendered the reference ({} spp) in {:.2} s",
        st.spp,
        t.elapsed().as_secs_f64()
    );
    let mut opts = filter::FilterOptions::new(&dump, cli.out.join("filtered"));
    // As --reference takes them: NAME.exr, or NAME_0000.exr, … beside it
    // (an animation's first file named instead found no frames).
    opts.reference = Some(cli.out.join(format!("{ref_name}.exr")));
    opts.albedo = Some(cli.out.join(format!("{}.exr", aux_names[0])));
    opts.normal = Some(cli.out.join(format!("{}.exr", aux_names[1])));
    // The demo shows the comparison: every image this machine can make.
    opts.config.methods = MethodSet::available();
    let report = filter::filter_with_progress(&opts, &Bar::new("filter"))?;
    print!("{}", report.summary());
    println!(
        "report: {}",
        cli.out.join("filtered").join("report.html").display()
    );
    Ok(())
}

/// Makes `out` the demo's folder, holding `names`: new, empty or a
/// previous demo's (its marker lists what it holds), so that files the
/// demo did not write are never overwritten.
fn claim(out: &Path, names: &[String]) -> anyhow::Result<()> {
    Inputs::default().check_dir(out)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    // What an earlier demo (of another scene) wrote stays ours too.
    let mut all = guard::marked(out).unwrap_or_default();
    all.extend(
        names
            .iter()
            .filter(|n| !all.contains(n))
            .cloned()
            .collect::<Vec<_>>(),
    );
    Ok(guard::write_marker(out, &all)?)
}

fn main() -> ExitCode {
    pathdensity::cli::run_main("demo", || run(Cli::parse()))
}
