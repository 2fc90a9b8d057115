//! `tiltsim completions SHELL`: the shell's completion script for every command and option,
//! generated from the command line's own definition.

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct CompletionsArgs {
    /// The shell.
    shell: clap_complete::Shell,
}

/// Prints the script to stdout (for example `tiltsim completions bash >
/// ~/.local/share/bash-completion/completions/tiltsim`).
pub fn exec(a: CompletionsArgs, cmd: &mut clap::Command) -> super::CliResult {
    clap_complete::generate(a.shell, cmd, "tiltsim", &mut std::io::stdout());
    Ok(())
}
