//! The allowed name closest to a misspelt one, for "did you mean" hints: a choice in a scenario
//! file or `--set` (`controller.mode = "mcp"`), a key (`[run] sede = 2`) and an enumerated
//! option on the command line (`--controller mcp`).

/// The allowed name nearest to `given` in edits (insertions, deletions, substitutions and
/// swaps of two neighbouring characters, ignoring case), if it is near enough to be the one
/// meant: one edit for a name of up to four characters, two up to eight, three beyond. Ties
/// go to the name listed first. A swap counts once, so `mcp` finds `mpc` (a Jaro similarity,
/// which clap uses, scores those two 0.56 and suggests nothing).
pub fn closest<'a>(given: &str, allowed: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let g = given.to_lowercase();
    let reach = match g.chars().count() {
        0 => return None,
        1..=4 => 1,
        5..=8 => 2,
        _ => 3,
    };
    let mut best: Option<(usize, &'a str)> = None;
    for name in allowed {
        let d = strsim::osa_distance(&g, &name.to_lowercase());
        if d <= reach && best.is_none_or(|(b, _)| d < b) {
            best = Some((d, name));
        }
    }
    best.map(|(_, n)| n)
}

/// For a serde message naming an unknown choice or key and what is expected (`unknown
/// variant `mcp`, expected one of `passive`, `pi`, `lqg`, `mpc``, `unknown field `sede`,
/// expected `seed` or `dt_s``), the expected name closest to the one written.
pub fn in_message(message: &str) -> Option<String> {
    let (_, rest) = message
        .split_once("unknown variant `")
        .or_else(|| message.split_once("unknown field `"))?;
    let (given, rest) = rest.split_once('`')?;
    let (_, expected) = rest.split_once("expected ")?;
    let expected = expected.lines().next()?;
    let names = expected.split('`').skip(1).step_by(2);
    closest(given, names).map(str::to_string)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_swap_or_a_slip_finds_the_name_and_a_different_word_finds_none() {
        let modes = ["passive", "pi", "lqg", "mpc"];
        assert_eq!(closest("mcp", modes), Some("mpc"));
        assert_eq!(closest("MPC", modes), Some("mpc"));
        assert_eq!(closest("lgq", modes), Some("lqg"));
        assert_eq!(closest("pasive", modes), Some("passive"));
        assert_eq!(closest("fuzzy", modes), None);
        assert_eq!(closest("", modes), None);
        // Two slips in a short name are another word, not a typo.
        assert_eq!(closest("abc", modes), None);
        let transports = ["ipc", "in-process"];
        assert_eq!(closest("inprocess", transports), Some("in-process"));
        assert_eq!(closest("icp", transports), Some("ipc"));
    }

    #[test]
    fn the_messages_of_serde_give_their_expected_names() {
        assert_eq!(
            in_message("unknown variant `mcp`, expected one of `passive`, `pi`, `lqg`, `mpc`")
                .as_deref(),
            Some("mpc")
        );
        assert_eq!(
            in_message("unknown field `sede`, expected `seed` or `dt_s`").as_deref(),
            Some("seed")
        );
        assert_eq!(
            in_message("TOML parse error at line 3, column 1\n  |\n3 | mdoe = 1\n  | ^^^^\nunknown field `mdoe`, expected one of `mode`, `rho`\n")
                .as_deref(),
            Some("mode")
        );
        assert_eq!(
            in_message("invalid type: integer `3`, expected a string"),
            None
        );
        assert_eq!(
            in_message("unknown variant `zzzzzz`, expected `ipc` or `in-process`"),
            None
        );
    }
}
