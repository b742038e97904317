//! The `digiview` binary: parses the command line and hands over to `digiview::cli`.

use clap::Parser;

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        // With the log's reader gone (`digiview serve 2>&1 | head`, a closed terminal), a
        // failed write must cost the line, not panic the thread that logged it: that thread
        // may be the one that stops the server on SIGTERM.
        .log_internal_errors(false)
        .init();
    match digiview::cli::run(digiview::cli::Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", causes(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes, each once: many errors already name their cause in their own
/// message (`cannot read x.png: No such file or directory`), so a cause whose words are
/// already there is not repeated.
fn causes(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text = format!("{text}: {c}");
        }
    }
    text
}
