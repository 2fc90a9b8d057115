//! The command line's definition, checked without running anything: clap's own consistency
//! checks (every argument reachable, no two with one name or short flag, defaults among the
//! allowed values, requirements and conflicts naming arguments that exist), then what users
//! type most, parsed.

use clap::{CommandFactory, Parser};

use super::Cli;

#[test]
fn the_command_line_definition_is_consistent() {
    Cli::command().debug_assert();
}

#[test]
fn the_commands_of_the_readme_parse() {
    for line in [
        "tiltsim run scenarios/paper-lqg.toml",
        "tiltsim run scenarios/paper-mpc.toml --transport in-process --set controller.mpc.output_weight=5 -q",
        "tiltsim run scenarios/pi-drive.toml --free-run --duration 5 --out out/free",
        "tiltsim compare scenarios/pi-drive.toml scenarios/paper-lqg.toml scenarios/paper-mpc.toml",
        "tiltsim validate scenarios/paper-lqg.toml",
        "tiltsim linearize scenarios/pi-drive.toml --design-pi",
        "tiltsim replay-timing out/free",
        "tiltsim bench",
        "tiltsim route routes/winding-valley.csv scenarios/line-mpc.toml --rho 0.3,0.55,0.7,1.0 --cd-tilting 200,275",
    ] {
        let args: Vec<&str> = line.split_whitespace().collect();
        if let Err(e) = Cli::try_parse_from(&args) {
            panic!("{line}: {e}");
        }
    }
    // A mistyped option is refused, not ignored.
    assert!(Cli::try_parse_from(["tiltsim", "run", "x.toml", "--transprot", "ipc"]).is_err());
}
