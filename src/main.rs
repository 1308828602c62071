//! The `fissure` command line: scenario checks and mesh tools (the simulator's
//! `run`, `replay`, `study` and `screenshot` join the same subcommand enum).
//!
//! In: arguments; `RUST_LOG` (tracing's env-filter syntax; default: fissure's
//! warnings and other crates' errors, `RUST_LOG=warn` shows theirs too).
//! Out: the command's output on stdout; log lines on stderr (no colours unless
//! stderr is a terminal); on error the whole cause chain on stderr. Exit codes:
//! 0 done, 1 error, 2 usage error (from clap), 3 `replay --strict` on a run
//! that failed its integrity limits ([`cli::IntegrityFailed`]; every output
//! written), 130 interrupted by Ctrl-C after writing what was done so far
//! ([`cli::Interrupted`]).
//! `anyhow` lives only here; the library returns typed errors.

mod cli;

use std::io::IsTerminal;
use std::process::ExitCode;

use clap::Parser;

/// Exit code of a run stopped by Ctrl-C (128 + SIGINT, as a shell reports it).
const EXIT_INTERRUPTED: u8 = 130;
/// Exit code of `replay --strict` when the run failed its integrity limits.
const EXIT_INTEGRITY: u8 = 3;

/// What is logged without `RUST_LOG`: fissure's warnings, other crates' errors
/// (winit and egui warn about display quirks, e.g. under Xvfb, that need no action).
const DEFAULT_LOG: &str = "error,fissure=warn";

/// Log to stderr through `tracing`: `RUST_LOG` when set and valid, else [`DEFAULT_LOG`].
fn install_logging() {
    let filter = match std::env::var("RUST_LOG") {
        Ok(spec) if !spec.trim().is_empty() => match tracing_subscriber::EnvFilter::try_new(&spec) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("fissure: RUST_LOG={spec:?} is not a valid filter ({e}); using {DEFAULT_LOG:?}");
                tracing_subscriber::EnvFilter::new(DEFAULT_LOG)
            }
        },
        _ => tracing_subscriber::EnvFilter::new(DEFAULT_LOG),
    };
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
}

/// The window on a software renderer (Mesa's llvmpipe, where no GPU is) must
/// leave the simulation a core: llvmpipe rasterizes on every core by default,
/// and on two cores the simulation's step p95 was 5.9-6.4 ms at 1280x800 under
/// Xvfb against 1.5-1.9 ms with one llvmpipe thread (docs/performance.md,
/// "The window's frame time"). Sets
/// `LP_NUM_THREADS` to cores - 1 for a windowed run unless the user set it; a
/// real GPU's driver never reads it.
fn leave_a_core_for_the_simulation(args: &cli::Cli) {
    let windowed = match &args.command {
        None => true,
        Some(cli::Command::Run { headless, .. }) => !headless,
        Some(_) => false,
    };
    if !windowed || std::env::var_os("LP_NUM_THREADS").is_some() {
        return;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // SAFETY: called first thing in `main`, before any other thread exists
    // (logging, the runtime's threads, the GPU driver all start later), so no
    // thread can read the environment concurrently.
    unsafe { std::env::set_var("LP_NUM_THREADS", cores.saturating_sub(1).max(1).to_string()) };
}

/// Output piped into a reader that stops early (`fissure mesh info M --json |
/// head`) ends the program quietly, as it ends any Unix tool, instead of a
/// panic in `println!`. Rust ignores SIGPIPE by default; the default action is
/// restored for the process. Sockets are not affected: the standard library
/// sends on a `TcpStream` with `MSG_NOSIGNAL`, so a tracker that drops its
/// connection still comes back as an error the OpenIGTLink server handles.
fn quiet_on_closed_pipes() {
    #[cfg(target_os = "linux")]
    // SAFETY: called first thing in `main`, before any other thread exists;
    // resetting a signal's disposition to its default has no other effect.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    quiet_on_closed_pipes();
    let args = cli::Cli::parse();
    leave_a_core_for_the_simulation(&args);
    install_logging();
    match cli::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            if let Some(interrupted) = error.downcast_ref::<cli::Interrupted>() {
                eprintln!("fissure: {interrupted}");
                return ExitCode::from(EXIT_INTERRUPTED);
            }
            if let Some(failed) = error.downcast_ref::<cli::IntegrityFailed>() {
                eprintln!("fissure: {failed}");
                return ExitCode::from(EXIT_INTEGRITY);
            }
            eprintln!("error: {error}");
            for cause in error.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}
