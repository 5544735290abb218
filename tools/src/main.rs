use clap::Parser;

/// beamtool: model, identify, shape and verify a flexible beam on a linear-motor carriage.
#[derive(Parser)]
#[command(name = "beamtool", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {}
}
