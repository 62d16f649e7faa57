//! `vestnav completions SHELL` and `vestnav man`: shell completion scripts and the man page, both generated
//! from the clap command tree in `cli.rs`, so they cannot drift from the options the program accepts.
//!
//! Both subcommands are hidden from the main help (an operator never needs them) and named in its footer.

use std::io::Write;

use clap::{Args, CommandFactory};
use clap_complete::Shell;

use crate::cli::Cli;

/// `vestnav completions SHELL`
#[derive(Debug, Args)]
#[command(after_help = "Install, for example:
  bash:  vestnav completions bash > ~/.local/share/bash-completion/completions/vestnav
  zsh:   vestnav completions zsh > ~/.zfunc/_vestnav   (with fpath+=~/.zfunc before compinit)
  fish:  vestnav completions fish > ~/.config/fish/completions/vestnav.fish
  PowerShell:  vestnav completions powershell | Out-String | Invoke-Expression
The man page: vestnav man > ~/.local/share/man/man1/vestnav.1")]
pub struct CompletionsArgs {
    /// The shell to write the completion script for.
    #[arg(value_enum)]
    pub shell: Shell,
}

/// Writes the completion script for `args.shell` to standard output.
pub fn run_completions(args: &CompletionsArgs) -> anyhow::Result<()> {
    let mut cmd = Cli::command();
    let name = cmd.get_name().to_owned();
    // `generate` panics on a write error; into memory it cannot fail, and a closed pipe on the real write
    // stays an error main.rs ends quietly on.
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut cmd, name, &mut script);
    let mut out = std::io::stdout().lock();
    out.write_all(&script)?;
    out.flush()?;
    Ok(())
}

/// Writes the man page (section 1, roff) to standard output.
pub fn run_man() -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    clap_mangen::Man::new(Cli::command()).render(&mut out)?;
    out.flush()?;
    Ok(())
}
