//! `croprow rows CLOUD --out rows.geojson`: every crop row of a whole-field point-cloud map (PCD, PLY,
//! LAS or text) as GeoJSON LineStrings with the row spacing, in the cloud's own frame and units.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use croprow_core::mapping::{Config, Extractor};
use croprow_io::maps;

/// Arguments of `croprow rows`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The field map: .pcd, .ply, .las, or whitespace-separated text (.txt, .xyz, .pts) `x y z ...`.
    pub cloud: PathBuf,
    /// Where to write the GeoJSON FeatureCollection (one LineString per row).
    #[arg(long)]
    pub out: PathBuf,
    /// A TOML file whose `[mapping]` table overrides the extraction settings (other tables are ignored).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = match &args.config {
        Some(path) => load_config(path)?,
        None => Config::default(),
    };
    let extractor = Extractor::new(config).context("invalid mapping configuration")?;
    // Open the output first: a typo in its path should not cost the reading and extraction.
    let out =
        std::fs::File::create(&args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    let started = Instant::now();
    let extracted = maps::read(&args.cloud).map_err(anyhow::Error::from).and_then(|cloud| {
        let read_s = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let map = extractor
            .extract(&cloud.points)
            .with_context(|| format!("no rows extracted from {}", args.cloud.display()))?;
        Ok((cloud.points.len(), cloud.non_finite, read_s, map, started.elapsed().as_secs_f64()))
    });
    let (points, non_finite, read_s, map, extract_s) = match extracted {
        Ok(done) => done,
        Err(e) => {
            // No half-made output: the empty file opened above goes.
            drop(out);
            let _ = std::fs::remove_file(&args.out);
            return Err(e);
        }
    };
    let mut out = std::io::BufWriter::new(out);
    serde_json::to_writer_pretty(&mut out, &maps::rows_to_geojson(&map))
        .map_err(anyhow::Error::from)
        .and_then(|()| out.flush().map_err(anyhow::Error::from))
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    eprintln!(
        "{}: {} points read in {read_s:.2} s ({non_finite} non-finite skipped); {} rows, spacing {:.3} m, direction {:.1}°, slice {:.2}-{:.2} m above ground \
         (periodicity {:.2}), extracted in {extract_s:.2} s -> {}",
        args.cloud.display(),
        points,
        map.rows.len(),
        map.spacing_m,
        map.direction_rad.to_degrees(),
        map.slice.min_m,
        map.slice.max_m,
        map.slice.periodicity,
        args.out.display(),
    );
    Ok(())
}

/// The `[mapping]` table of a TOML config file (defaults for what it does not name).
fn load_config(path: &PathBuf) -> anyhow::Result<Config> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut table: toml::Table =
        toml::from_str(&text).with_context(|| format!("{} is not valid TOML", path.display()))?;
    match table.remove("mapping") {
        Some(section) => {
            section.try_into().with_context(|| format!("{}: bad [mapping] table", path.display()))
        }
        None => Ok(Config::default()),
    }
}
