//! `beamtool`: parses the command line and runs it ([`beamtools::cli`]); errors are printed as
//! `error: …` (with their causes) and exit with status 1.

use clap::Parser;

fn main() {
    let cli = beamtools::cli::Cli::parse();
    if let Err(e) = beamtools::cli::run(cli.command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
