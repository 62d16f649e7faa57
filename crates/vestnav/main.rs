//! vestnav: the console (no subcommand) and headless subcommands.
//!
//! This file only parses the command line and dispatches; each subcommand family lives in its own module.

mod analyze;
mod cli;
mod emulate_gps;
mod emulate_vest;
mod fieldtest;
mod nav;
mod nmea;
mod sim_tactor;
mod sim_wave;

use clap::Parser;

use cli::{
    AnalyzeCommand, Cli, Command, EmulateCommand, FieldtestCommand, NavCommand, NmeaCommand, SimCommand,
};

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("vestnav: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let Some(command) = cli.command else {
        return vestnav_app::run();
    };
    match command {
        Command::Sim(SimCommand::Tactor(a)) => sim_tactor::run_tactor(&a),
        Command::Sim(SimCommand::Sweep(a)) => sim_tactor::run_sweep(&a),
        Command::Sim(SimCommand::DampingFor(a)) => sim_tactor::run_damping_for(&a),
        Command::Sim(SimCommand::TwoPoint(a)) => sim_wave::run_two_point(&a),
        Command::Sim(SimCommand::Wave(a)) => sim_wave::run_wave(&a),
        Command::Analyze(AnalyzeCommand::TactorData(a)) => analyze::run_tactor_data(&a),
        Command::Nmea(NmeaCommand::Decode(a)) => nmea::run_decode(&a),
        Command::Nmea(NmeaCommand::Record(a)) => nmea::run_record(&a),
        Command::Emulate(EmulateCommand::Vest(a)) => emulate_vest::run(&a),
        Command::Emulate(EmulateCommand::Gps(a)) => emulate_gps::run(&a),
        Command::Nav(NavCommand::Simulate(a)) => nav::run_simulate(&a),
        Command::Fieldtest(FieldtestCommand::Drift(a)) => fieldtest::run_drift(&a),
        Command::Fieldtest(FieldtestCommand::Cones(a)) => fieldtest::run_cones(&a),
    }
}
