//! `vestnav study ...`: tactile-display experiments (docs/study.md). `check` validates a protocol and prints
//! its plan, `analyze` reads a results CSV; both are thin over `vestnav_core::study` and
//! `vestnav_report::study`.

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use clap::{Args, Subcommand};
use vestnav_core::study::{Protocol, analyze, plan};

/// `vestnav study ...`
#[derive(Debug, Subcommand)]
pub enum StudySubcommand {
    /// Validate a study protocol (TOML) against the format and the vest unit's limits, and print its plan;
    /// every problem is printed with its line, and the exit status is 1 when there is any.
    Check(CheckArgs),
    /// Analyse a results CSV: percent correct, confusion, information transfer, response times, learning
    /// curve, localization map, navigation summaries; optionally the figures as PNG.
    Analyze(AnalyzeArgs),
    /// Run one session of a protocol on the vest: prompts for each response (or a simulated wearer),
    /// results appended to a new CSV after every trial, JSON at the end.
    Run(Box<crate::study_run::StudyRunArgs>),
}

/// `vestnav study check`.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The protocol file.
    #[arg(value_name = "PROTOCOL.toml")]
    pub protocol: PathBuf,
    /// Print every trial of this participant's plan (one line each: trial, block, training, feedback,
    /// stimulus).
    #[arg(long, value_name = "ID")]
    pub participant: Option<String>,
}

/// `vestnav study analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
    /// The results CSV written by a study run.
    #[arg(value_name = "RESULTS.csv")]
    pub results: PathBuf,
    /// Print the analysis as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write the figures (PNG) into this existing folder.
    #[arg(long, value_name = "DIR")]
    pub figures: Option<PathBuf>,
}

/// Runs one `vestnav study` subcommand.
pub fn run(command: &StudySubcommand) -> anyhow::Result<()> {
    match command {
        StudySubcommand::Check(a) => run_check(a),
        StudySubcommand::Analyze(a) => run_analyze(a),
        StudySubcommand::Run(a) => crate::study_run::run(a),
    }
}

#[allow(clippy::print_stdout)]
fn run_check(args: &CheckArgs) -> anyhow::Result<()> {
    let limits = vestnav_device::wtcu::Limits::default();
    let checked = Protocol::load(&args.protocol).and_then(|p| {
        p.check_stimuli(|pattern| {
            limits.check_pattern(&pattern.frames, pattern.repeats).map_err(|e| e.to_string())
        })?;
        Ok(p)
    });
    let p = match checked {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            bail!("{}: {} problem(s)", args.protocol.display(), e.problems.len());
        }
    };
    println!("{}: {} protocol {:?}, valid", args.protocol.display(), p.task.name(), p.name);
    if !p.description.is_empty() {
        println!("  {}", p.description);
    }
    println!(
        "  {} stimuli, {} blocks, {} trials per participant, order {} (seed {})",
        p.stimuli.len(),
        p.blocks.len(),
        p.trials_per_participant(),
        p.order.name(),
        p.seed
    );
    for (i, b) in p.blocks.iter().enumerate() {
        println!(
            "  block {:?}: {} x {} trials, {}, feedback {}, order {}; timing keys: {} (the station's for the rest)",
            b.name,
            b.repetitions,
            p.stimuli.len(),
            if b.training { "training" } else { "test" },
            if b.feedback { "on" } else { "off" },
            b.order.name(),
            p.block_timing(i).summary()
        );
    }
    let choices = p.choices();
    if !choices.is_empty() {
        println!("  choices: {}", choices.join(", "));
    }
    if !p.sessions.is_empty() {
        println!("  sessions: {}", p.sessions.join(", "));
    }
    for who in &p.participants {
        let trials = plan(&p, who)?;
        let first: Vec<String> = trials.iter().take(12).map(|t| t.answer.clone()).collect();
        let more = if trials.len() > first.len() { ", ..." } else { "" };
        println!("  {who}: {} trials: {}{more}", trials.len(), first.join(", "));
    }
    if let Some(who) = &args.participant {
        let trials = plan(&p, who).with_context(|| format!("--participant {who}"))?;
        println!("trial\tblock\ttraining\tfeedback\tstimulus");
        for t in trials {
            println!(
                "{}\t{}\t{}\t{}\t{}",
                t.index,
                t.block_name,
                u8::from(t.training),
                u8::from(t.feedback),
                t.answer
            );
        }
    }
    Ok(())
}

#[allow(clippy::print_stdout)]
fn run_analyze(args: &AnalyzeArgs) -> anyhow::Result<()> {
    let rows = vestnav_core::study::record::read_csv_file(&args.results).map_err(anyhow::Error::msg)?;
    let analysis = analyze(&rows);
    if args.json {
        print!("{}", vestnav_report::to_json(&analysis)?);
    } else {
        for line in analysis.summary_lines() {
            println!("{line}");
        }
    }
    if let Some(dir) = &args.figures {
        let written = vestnav_report::study::figures(&analysis, dir).context("--figures")?;
        for path in written {
            // Standard output stays pure JSON with --json.
            if args.json {
                eprintln!("figure: {}", path.display());
            } else {
                println!("figure: {}", path.display());
            }
        }
    }
    Ok(())
}
