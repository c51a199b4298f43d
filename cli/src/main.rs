//! `cryofit`: the one binary users run. Parses the command line and hands over to a command.

mod bench;
mod calibrate;
mod client;
mod compare;
mod crossval;
mod csv_text;
mod fluid_source;
mod healthcheck;
mod output;
mod param_values;
mod params_cmd;
mod predict;
mod progress;
mod props;
mod report;
mod serve;
mod simulate;
mod work;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Cryogenic two-phase flow: chilldown simulation, calibration and parameter studies.
#[derive(Debug, Parser)]
#[command(
    name = "cryofit",
    version,
    about = "Cryogenic two-phase flow: chilldown simulation, calibration and parameter studies."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Fluid properties at a pressure and temperature (from the built-in CoolProp tables).
    Props(props::PropsArgs),
    /// Run a case file and write probes.csv, profiles.csv and summary.json.
    Simulate(simulate::SimulateArgs),
    /// Fit registry parameters to measured data (stages: sensitivity, global search, variance, posterior).
    Calibrate(calibrate::CalibrateArgs),
    /// Predict an untested case over the posterior of a calibration (median and 5–95 % bands).
    Predict(predict::PredictArgs),
    /// Compare calibrations of the same data: best cost, AIC, BIC, Laplace evidence and Bayes factors.
    Compare(compare::CompareArgs),
    /// Leave-one-out cross-validation of a joint calibration: refit without each experiment, predict it.
    Crossval(crossval::CrossvalArgs),
    /// List the model parameters: name, group, default, bounds, unit and meaning.
    Params(params_cmd::ParamsArgs),
    /// Measurements too heavy for the test suite (robustness over the parameter space).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Run the coordinator: REST API, SQLite storage, optimiser driver and job leases.
    Serve(serve::ServeArgs),
    /// Run a worker: claim jobs from a coordinator, simulate, report costs.
    Work(work::WorkArgs),
    /// Upload a calibration file's experiments and the calibration to a coordinator.
    Submit(client::SubmitArgs),
    /// Show a calibration's status, progress and best parameters.
    Status(client::StatusArgs),
    /// Print every result of a calibration (JSON or CSV).
    Results(client::ResultsArgs),
    /// Cancel a calibration.
    Cancel(client::CancelArgs),
    /// Exit 0 when a coordinator's /healthz answers ok (for container health checks).
    Healthcheck(healthcheck::HealthcheckArgs),
    /// Draw a calibration's figures (SVG and PNG) with an index.html, from an output folder or a coordinator.
    Report(report::ReportArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = e.print();
                return if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                    ExitCode::from(2)
                } else {
                    ExitCode::SUCCESS
                };
            }
            // one line: clap's first paragraph names the argument and the problem
            let text = e.render().to_string();
            let first: Vec<&str> = text.lines().map(str::trim).take_while(|l| !l.is_empty()).collect();
            eprintln!("{} (see 'cryofit --help')", first.join(" "));
            return ExitCode::from(2);
        }
    };
    // A reader that closes stdout early (`cryofit params | head`) makes the next print fail;
    // the standard library reports that as a panic. It is no defect: the reader has what it
    // wanted. The hook keeps that one quiet, and the run ends as a pipe's writer does.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_broken_pipe(info.payload()) {
            default_hook(info);
        }
    }));
    let result = match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| dispatch(cli.command))) {
        Ok(result) => result,
        Err(payload) if is_broken_pipe(payload.as_ref()) => return ExitCode::from(BROKEN_PIPE_EXIT),
        Err(payload) => std::panic::resume_unwind(payload),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Exit status when stdout was closed under the command: 128 + SIGPIPE, what a shell reports
/// for a writer that a pipe's reader left.
const BROKEN_PIPE_EXIT: u8 = 141;

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Props(args) => props::run(&args),
        Command::Bench(cmd) => bench::run(&cmd),
        Command::Simulate(args) => simulate::run(&args),
        Command::Calibrate(args) => calibrate::run(&args),
        Command::Predict(args) => predict::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Crossval(args) => crossval::run(&args),
        Command::Params(args) => params_cmd::run(&args),
        Command::Serve(args) => serve::run(&args),
        Command::Work(args) => work::run(&args),
        Command::Submit(args) => client::submit(&args),
        Command::Status(args) => client::status(&args),
        Command::Results(args) => client::results(&args),
        Command::Cancel(args) => client::cancel(&args),
        Command::Healthcheck(args) => healthcheck::run(&args),
        Command::Report(args) => report::run(&args),
    }
}

/// Whether a panic payload is the standard library's report of a print to a closed stdout.
fn is_broken_pipe(payload: &(dyn std::any::Any + Send)) -> bool {
    let message = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("");
    message.starts_with("failed printing to stdout") && message.contains("Broken pipe")
}
