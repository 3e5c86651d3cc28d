//! `lavatube world export`: the world a config describes as a mesh file any viewer opens.

use anyhow::Context;
use common::Config;
use common::terrain::Terrain;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Subcommand)]
pub enum WorldCommand {
    /// Write the world's floor as a Wavefront OBJ mesh (Y up, metres).
    Export(ExportArgs),
}

#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The config whose world to write (default: the built-in one).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The OBJ file to write.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn world(command: WorldCommand) -> anyhow::Result<ExitCode> {
    let WorldCommand::Export(args) = command;
    let cfg = match &args.config {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    let terrain = Terrain::build(&cfg.sim.terrain).map_err(|e| super::UserError(e.to_string()))?;
    let tmp = args.out.with_extension("obj.part");
    let file =
        std::fs::File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    let mut out = std::io::BufWriter::new(file);
    common::obj::write(&terrain, "floor", &mut out)
        .and_then(|()| out.flush())
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, &args.out)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    let (rows, cols) = terrain.dims();
    println!(
        "wrote {} ({} vertices, {} triangles)",
        args.out.display(),
        rows * cols,
        2 * (rows - 1) * (cols - 1)
    );
    Ok(ExitCode::SUCCESS)
}
