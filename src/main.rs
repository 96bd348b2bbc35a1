//! The `pathdensity` command line: parses arguments and calls the library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};

use pathdensity::commands::batch::{self, BatchOptions, shard::Shard};
use pathdensity::commands::{filter, info, regress, sweep};
use pathdensity::config::{
    ColorSpace, ConfigError, Denoise, FilterConfig, FinalPass, MethodSet, Recon, White,
};
use pathdensity::density::IndexKind;
use pathdensity::dump::Order;
use pathdensity::imagespace::aux::AuxPrefilter;
use pathdensity::pipeline::PipelineError;
use pathdensity::sweep::SweepOptions;
use pathdensity::synth::SynthParams;

use pathdensity::cli::Bar;

#[derive(Parser)]
#[command(
    name = "pathdensity",
    version,
    about = "Density-based outlier rejection for Monte Carlo sample dumps"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Every field of [`FilterConfig`] as a flag; the defaults are
/// [`FilterConfig::DEFAULT`]'s.
#[derive(Args)]
struct ConfigArgs {
    /// Neighbours whose mean distance σ decides a sample (σ < 1 accepts).
    #[arg(long, default_value_t = D.k)]
    k: usize,
    /// Joint-space scale of the image axes, in pixels.
    #[arg(long, default_value_t = D.sigma_image)]
    sigma_image: f64,
    /// Joint-space scale of the colour axes, in CIELAB units.
    #[arg(long, default_value_t = D.sigma_color)]
    sigma_color: f64,
    /// Joint-space scale of the time axis, in frames (animations).
    #[arg(long, default_value_t = D.sigma_time)]
    sigma_time: f64,
    /// Luminance of white (radiance that maps to L* = 100), or `auto`:
    /// the dump's median positive luminance maps to L* = 50.
    #[arg(long, default_value_t = D.white)]
    white: White,
    /// box or gaussian.
    #[arg(long, default_value_t = D.recon)]
    recon: Recon,
    /// grid or kdtree (results do not depend on it).
    #[arg(long, default_value_t = D.index)]
    index: IndexKind,
    /// The images besides mean and filtered, instead of the default ones
    /// (filtered_energy and the recommended image: guided_oidn where OIDN
    /// is found, else guided); `all` for every image this machine can make.
    #[arg(long, value_delimiter = ',')]
    methods: Option<Vec<MethodSet>>,
    /// α of the trimmed mean: ⌊α n⌋ samples dropped at each end.
    #[arg(long, default_value_t = D.alpha)]
    alpha: f64,
    /// Spatial σ of the bilateral filter, in pixels.
    #[arg(long, default_value_t = D.bilateral_sigma_s)]
    bilateral_sigma_s: f64,
    /// Range σ of the bilateral filter, in CIELAB ΔE.
    #[arg(long, default_value_t = D.bilateral_sigma_r)]
    bilateral_sigma_r: f64,
    /// Groups of the median of means (mon, gmon).
    #[arg(long, default_value_t = D.mon_groups)]
    mon_groups: usize,
    /// rwmc: number of cascades S.
    #[arg(long, default_value_t = D.rwmc_cascades)]
    rwmc_cascades: usize,
    /// rwmc: luminance s₀ where the second cascade starts.
    #[arg(long, default_value_t = D.rwmc_start)]
    rwmc_start: f64,
    /// rwmc: ratio b between cascades.
    #[arg(long, default_value_t = D.rwmc_base)]
    rwmc_base: f64,
    /// rwmc: κ, samples a bright feature needs to be trusted.
    #[arg(long, default_value_t = D.rwmc_kappa)]
    rwmc_kappa: f64,
    /// rwmc: luminance always considered reliable.
    #[arg(long, default_value_t = D.rwmc_min_luminance)]
    rwmc_min_luminance: f64,
    /// filtered_energy: σ (pixels) of the spread of the removed energy.
    #[arg(long, default_value_t = D.energy_sigma)]
    energy_sigma: f64,
    /// clamp: the largest RGB component a sample may keep.
    #[arg(long, default_value_t = D.clamp)]
    clamp: f64,
    /// guided: z of the accepted samples' confidence interval.
    #[arg(long, default_value_t = D.guide_z)]
    guide_z: f64,
    /// guided, guided_oidn: decide white channels (guided) or white pixels
    /// (guided_oidn) by held-out halves of the samples (`false`: faster,
    /// each image made once; docs/filter.md F10).
    #[arg(long, default_value_t = D.held_out, action = clap::ArgAction::Set)]
    held_out: bool,
    /// Exposure of the PNG previews and the display metrics.
    #[arg(long, default_value_t = D.exposure)]
    exposure: f64,
    /// `oidn`: also denoise every selected method's image with Intel Open
    /// Image Denoise (METHOD+oidn; needs an OIDN found at run time: README, "OIDN").
    #[arg(long, default_value_t = D.denoise)]
    denoise: Denoise,
    /// Colour coordinates of the joint space: cielab (the paper's), loglab
    /// or logluv (logarithmic above the white; docs/filter.md §1).
    #[arg(long, default_value_t = D.color_space)]
    color_space: ColorSpace,
    /// What the final pass judges a stored sample against: `stored` (the
    /// paper's) or `all` valid samples (docs/filter.md §2, F6a).
    #[arg(long, default_value_t = D.final_pass)]
    final_pass: FinalPass,
}

const D: FilterConfig = FilterConfig::DEFAULT;

impl From<ConfigArgs> for FilterConfig {
    fn from(a: ConfigArgs) -> FilterConfig {
        FilterConfig {
            k: a.k,
            sigma_image: a.sigma_image,
            sigma_color: a.sigma_color,
            sigma_time: a.sigma_time,
            white: a.white,
            recon: a.recon,
            index: a.index,
            methods: a.methods.map_or_else(MethodSet::default_here, |sets| {
                sets.into_iter().fold(MethodSet::CORE, MethodSet::union)
            }),
            alpha: a.alpha,
            bilateral_sigma_s: a.bilateral_sigma_s,
            bilateral_sigma_r: a.bilateral_sigma_r,
            mon_groups: a.mon_groups,
            rwmc_cascades: a.rwmc_cascades,
            rwmc_start: a.rwmc_start,
            rwmc_base: a.rwmc_base,
            rwmc_kappa: a.rwmc_kappa,
            rwmc_min_luminance: a.rwmc_min_luminance,
            energy_sigma: a.energy_sigma,
            clamp: a.clamp,
            guide_z: a.guide_z,
            held_out: a.held_out,
            exposure: a.exposure,
            denoise: a.denoise,
            color_space: a.color_space,
            final_pass: a.final_pass,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum OrderArg {
    Pixel,
    Pass,
}

#[derive(Subcommand)]
enum Command {
    /// Print a dump's header, invalid records and radiance statistics.
    Info {
        /// The sample dump (.pds).
        dump: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Run the path-density filter and write images and a report.
    #[command(allow_negative_numbers = true)]
    Filter {
        /// The sample dump (.pds) to filter.
        dump: PathBuf,
        /// Output folder; replaced whole by this run's files when it ends.
        #[arg(short, long)]
        out: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Reference EXR (for an animation, REF.exr names REF_0000.exr, …).
        #[arg(long)]
        reference: Option<PathBuf>,
        /// The renderer's albedo EXR: OIDN's auxiliary input, and which
        /// pixels statmc averages (an animation's as for --reference).
        #[arg(long)]
        albedo: Option<PathBuf>,
        /// The renderer's normal EXR, OIDN's and statmc's as the albedo
        /// (needs --albedo).
        #[arg(long)]
        normal: Option<PathBuf>,
        /// How OIDN treats --albedo and --normal: `accurate` denoises them
        /// first (right whether they are noisy or not), `none` takes them
        /// as noise-free (rendered with many samples, or denoised),
        /// `fast` as they are, possibly noisy (Blender's names).
        #[arg(long, default_value_t = AuxPrefilter::default(), requires = "albedo")]
        aux_prefilter: AuxPrefilter,
        /// Worker threads (default: one per core).
        #[arg(long, default_value_t = 0, value_parser = pathdensity::cli::threads)]
        threads: usize,
        /// Write one decision byte per record to this file.
        #[arg(long)]
        decisions: Option<PathBuf>,
        /// Also write sigma.exr (exact σ of every sample; slower).
        #[arg(long)]
        sigma_map: bool,
        /// Film row of the joint-density slice plot (default: the middle).
        #[arg(long)]
        slice_row: Option<u32>,
        /// Skip the PNG previews, σ map, slice plot and report.html (faster:
        /// no exact σ is needed).
        #[arg(long)]
        no_html: bool,
    },
    /// Filter many dumps with one configuration into OUTDIR/NAME/ each, and
    /// summarise them (summary.csv, .json, .html); resumable, shardable
    /// (docs/farm.md).
    #[command(allow_negative_numbers = true)]
    Batch {
        /// Dumps: paths or quoted glob patterns ('shots/*.pds').
        dumps: Vec<String>,
        /// A manifest: one dump a line, then per-dump options
        /// (--reference REF.exr, --name NAME, any configuration flag).
        #[arg(long)]
        manifest: Option<PathBuf>,
        /// Output folder: OUTDIR/NAME/ per dump, the summary beside them.
        #[arg(short, long, required_unless_present = "merge")]
        out: Option<PathBuf>,
        #[command(flatten)]
        config: ConfigArgs,
        /// Each dump's reference, {dir} and {stem} standing for the dump's
        /// folder and file stem: '{dir}/{stem}_ref.exr'.
        #[arg(long)]
        reference: Option<String>,
        /// Worker threads of each dump's filter (default: one per core).
        #[arg(long, default_value_t = 0, value_parser = pathdensity::cli::threads)]
        threads: usize,
        /// This process's share, I/N with 0 ≤ I < N (a Slurm array's
        /// $SLURM_ARRAY_TASK_ID/N); then `--merge OUTDIR`.
        #[arg(long, default_value_t = Shard::WHOLE)]
        shard: Shard,
        /// Filter every dump, even those whose outputs are up to date.
        #[arg(long)]
        force: bool,
        /// Build the summary from the shards' results in this OUTDIR.
        #[arg(long, value_name = "OUTDIR", conflicts_with_all = ["dumps", "manifest", "out", "shard", "force"])]
        merge: Option<PathBuf>,
        /// Also write each dump's sigma.exr.
        #[arg(long)]
        sigma_map: bool,
        /// Skip each dump's PNG previews, σ map and report.html (faster).
        #[arg(long)]
        no_html: bool,
    },
    /// Run the filter over a grid of k, σ_color, σ_image and white.
    #[command(allow_negative_numbers = true)]
    Sweep {
        /// The sample dump (.pds).
        dump: PathBuf,
        /// The reference EXR every configuration is measured against.
        #[arg(long)]
        reference: PathBuf,
        /// Output folder for sweep.csv, sweep.json, the plots and sweep.html.
        #[arg(short, long)]
        out: PathBuf,
        /// k values, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "5,10,20,50,200")]
        k: Vec<usize>,
        /// σ_color values, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "25,50,100,200,400")]
        sigma_color: Vec<f64>,
        /// σ_image values, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1.5,3,6")]
        sigma_image: Vec<f64>,
        /// White luminances, numbers or `auto`, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1")]
        white: Vec<White>,
        /// Colour spaces of the joint space, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = [D.color_space])]
        color_space: Vec<ColorSpace>,
        /// Final passes (stored, all), comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = [D.final_pass])]
        final_pass: Vec<FinalPass>,
        #[arg(long, default_value_t = D.sigma_time)]
        sigma_time: f64,
        #[arg(long, default_value_t = D.recon)]
        recon: Recon,
        #[arg(long, default_value_t = D.exposure)]
        exposure: f64,
        #[arg(long, default_value_t = 0, value_parser = pathdensity::cli::threads)]
        threads: usize,
        /// Instead of the grid: compare the filtered image of each prefix
        /// of a pass-major dump with the mean of equal total time, using the
        /// first value of each list.
        #[arg(long, requires = "render_seconds")]
        equal_time: bool,
        /// The dump's render time (the `render` command prints it).
        #[arg(long)]
        render_seconds: Option<f64>,
        /// Group counts of the mon and gmon baselines.
        #[arg(long, value_delimiter = ',', default_values_t = [D.mon_groups])]
        mon_groups: Vec<usize>,
        /// κ values of the rwmc baseline.
        #[arg(long, value_delimiter = ',', default_values_t = [D.rwmc_kappa])]
        rwmc_kappa: Vec<f64>,
        /// C values of the clamp baseline, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = [D.clamp])]
        clamp: Vec<f64>,
    },
    /// Re-run every regression fixture and compare with its expectations.
    Regress {
        /// The directory of fixtures (each a directory with manifest.json).
        #[arg(default_value = "fixtures")]
        dir: PathBuf,
        /// Rewrite the expectations after an intended change.
        #[arg(long)]
        bless: bool,
    },
    /// Write a dump from another renderer's per-sample data
    /// (docs/renderers.md).
    #[command(subcommand)]
    Import(ImportSource),
    /// Write a synthetic dump (smooth field, fireflies, optional small light).
    Synth {
        #[arg(short, long)]
        out: PathBuf,
        #[arg(long, default_value_t = 256)]
        width: u32,
        #[arg(long, default_value_t = 256)]
        height: u32,
        #[arg(long, default_value_t = 1)]
        frames: u32,
        #[arg(long, default_value_t = 64)]
        spp: u32,
        #[arg(long, value_enum, default_value_t = OrderArg::Pixel)]
        order: OrderArg,
        #[arg(long, default_value_t = 0.005)]
        fireflies: f64,
        /// Place every sample at its pixel centre.
        #[arg(long)]
        pixel_centre: bool,
        /// Add a small bright square light: X,Y,SIDE,RADIANCE.
        #[arg(long, value_parser = parse_light)]
        light: Option<(u32, u32, u32, f32)>,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

#[derive(Subcommand)]
enum ImportSource {
    /// N renders of one view at 1 spp with different seeds (EXR), in replay
    /// order: a pass-major dump of N spp, samples at pixel centres.
    Images {
        /// The images, in order.
        #[arg(required = true)]
        images: Vec<PathBuf>,
        /// The dump to write.
        #[arg(short, long)]
        out: PathBuf,
    },
    /// A numpy .npy array of shape (N, 6), float32: x, y, t, r, g, b.
    Npy {
        /// The .npy file.
        file: PathBuf,
        #[arg(long)]
        width: u32,
        #[arg(long)]
        height: u32,
        /// Samples per pixel per frame; when given, N must be
        /// width × height × frames × spp.
        #[arg(long, default_value_t = 0)]
        spp: u32,
        #[arg(long, default_value_t = 1)]
        frames: u32,
        /// The order the rows are in (the filter replays it).
        #[arg(long, value_enum)]
        order: Option<OrderArg>,
        /// The dump to write.
        #[arg(short, long)]
        out: PathBuf,
    },
    /// A BCD raw sample file (the input of BCD's raw2bcd): a pixel-major
    /// dump, samples at pixel centres.
    Bcd {
        /// The raw file.
        file: PathBuf,
        /// The dump to write.
        #[arg(short, long)]
        out: PathBuf,
    },
}

impl From<OrderArg> for Order {
    fn from(o: OrderArg) -> Order {
        match o {
            OrderArg::Pixel => Order::PixelMajor,
            OrderArg::Pass => Order::PassMajor,
        }
    }
}

fn import(source: ImportSource) -> anyhow::Result<()> {
    use pathdensity_import::{bcd, images, npy};
    let (out, done) = match source {
        ImportSource::Images { images, out } => {
            let r = images::import(&images, &out);
            (out, r)
        }
        ImportSource::Npy {
            file,
            width,
            height,
            spp,
            frames,
            order,
            out,
        } => {
            let film = npy::Film {
                width,
                height,
                frames,
                spp,
                order: order.map_or(Order::Unspecified, Order::from),
            };
            let r = npy::import(&file, film, &out);
            (out, r)
        }
        ImportSource::Bcd { file, out } => {
            let r = bcd::import(&file, &out);
            (out, r)
        }
    };
    println!("{}: {}", out.display(), done?);
    Ok(())
}

fn parse_light(s: &str) -> Result<(u32, u32, u32, f32), String> {
    let v: Vec<&str> = s.split(',').collect();
    let bad = || format!("expected X,Y,SIDE,RADIANCE, got {s:?}");
    if v.len() != 4 {
        return Err(bad());
    }
    Ok((
        v[0].parse().map_err(|_| bad())?,
        v[1].parse().map_err(|_| bad())?,
        v[2].parse().map_err(|_| bad())?,
        v[3].parse().map_err(|_| bad())?,
    ))
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Info { dump, json } => {
            let i = info::info(&dump)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&i)?);
            } else {
                print!("{}", info::render(&i));
            }
        }
        Command::Filter {
            dump,
            out,
            config,
            reference,
            albedo,
            normal,
            aux_prefilter,
            threads,
            decisions,
            sigma_map,
            slice_row,
            no_html,
        } => {
            let mut o = filter::FilterOptions::new(dump, out);
            o.config = config.into();
            o.reference = reference;
            o.albedo = albedo;
            o.normal = normal;
            o.aux_prefilter = aux_prefilter;
            o.threads = threads;
            o.decisions = decisions;
            o.sigma_map = sigma_map;
            o.slice_row = slice_row;
            o.html = !no_html;
            let report = filter::filter_with_progress(&o, &Bar::new("filter"))?;
            print!("{}", report.summary());
            if o.html {
                println!("report: {}", o.out_dir.join("report.html").display());
            }
        }
        Command::Batch {
            dumps,
            manifest,
            out,
            config,
            reference,
            threads,
            shard,
            force,
            merge,
            sigma_map,
            no_html,
        } => {
            let (outcome, shard) = match merge {
                Some(dir) => (batch::merge(&dir)?, Shard::WHOLE),
                None => {
                    let out = out.expect("clap requires --out without --merge");
                    let mut o = BatchOptions::new(dumps, out);
                    o.manifest = manifest;
                    o.config = config.into();
                    o.reference_pattern = reference;
                    o.threads = threads;
                    o.shard = shard;
                    o.force = force;
                    o.sigma_map = sigma_map;
                    o.html = !no_html;
                    (batch::batch(&o, &Bar::batch())?, shard)
                }
            };
            print!("{}", outcome.text(shard));
            if outcome.count(batch::Status::Failed) > 0 {
                return Ok(ExitCode::from(EXIT_SOME_FAILED));
            }
        }
        Command::Sweep {
            dump,
            reference,
            out,
            k,
            sigma_color,
            sigma_image,
            white,
            color_space,
            final_pass,
            sigma_time,
            recon,
            exposure,
            threads,
            equal_time,
            render_seconds,
            mon_groups,
            rwmc_kappa,
            clamp,
        } => {
            let mut o = SweepOptions::new(dump, reference, out);
            o.ks = k;
            o.sigma_colors = sigma_color;
            o.sigma_images = sigma_image;
            o.whites = white;
            o.color_spaces = color_space;
            o.final_passes = final_pass;
            o.config.sigma_time = sigma_time;
            o.config.recon = recon;
            o.config.exposure = exposure;
            o.threads = threads;
            o.mon_groups = mon_groups;
            o.rwmc_kappas = rwmc_kappa;
            o.clamps = clamp;
            match render_seconds.filter(|_| equal_time) {
                Some(secs) => print!("{}", sweep::equal_time(&o, secs, &Bar::new("prefixes"))?),
                None => print!(
                    "{}",
                    sweep::table(&sweep::sweep_with_progress(&o, &Bar::new("sweep"))?)
                ),
            }
        }
        Command::Import(source) => import(source)?,
        Command::Regress { dir, bless } => {
            let o = regress::regress(&dir, bless)?;
            print!("{}", o.text);
            if bless && o.drifted > 0 {
                eprintln!(
                    "pathdensity: {} of {} fixtures could not be blessed (each said why above)",
                    o.drifted, o.fixtures
                );
                return Ok(ExitCode::from(EXIT_INPUT));
            }
            if o.drifted > 0 {
                eprintln!(
                    "pathdensity: {} of {} fixtures drifted (after an intended change: regress --bless)",
                    o.drifted, o.fixtures
                );
                return Ok(ExitCode::from(EXIT_DRIFT));
            }
        }
        Command::Synth {
            out,
            width,
            height,
            frames,
            spp,
            order,
            fireflies,
            pixel_centre,
            light,
            seed,
        } => {
            let p = SynthParams {
                width,
                height,
                frames,
                spp,
                order: order.into(),
                firefly_fraction: fireflies,
                pixel_centre,
                light,
                seed,
                ..SynthParams::default()
            };
            let h = p.write(&out)?;
            println!("{}: {} samples", out.display(), h.sample_count);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Exit codes (docs/commands.md, "Exit codes"): bad input or I/O, a usage error
/// (clap's own, or an option value the configuration refuses), a
/// regression fixture that drifted, a batch in which some dumps failed.
const EXIT_INPUT: u8 = 1;
const EXIT_USAGE: u8 = 2;
const EXIT_DRIFT: u8 = 3;
const EXIT_SOME_FAILED: u8 = 4;

fn main() -> ExitCode {
    pathdensity::cli::clean_up_on_signals();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            // A configuration field is a flag here: `sigma_color` is --sigma-color.
            let config_error = e.chain().find_map(|c| {
                c.downcast_ref::<ConfigError>().or(match c.downcast_ref() {
                    Some(PipelineError::Config(c)) => Some(c),
                    _ => None,
                })
            });
            if let Some(c) = config_error {
                eprintln!("pathdensity: --{} {}", c.field.replace('_', "-"), c.problem);
                return ExitCode::from(EXIT_USAGE);
            }
            eprintln!("pathdensity: {e:#}");
            ExitCode::from(EXIT_INPUT)
        }
    }
}
