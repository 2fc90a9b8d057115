//! Subscripts and superscripts in a chart's text: `θ_{v}^{d}` is θ with a subscript v and a
//! superscript d. Only the braced forms are markup, so a name such as `u_max_deg` stays as
//! written.

/// Where a run of text sits relative to the baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shift {
    /// On the baseline.
    Base,
    /// Lowered, smaller.
    Sub,
    /// Raised, smaller.
    Super,
}

/// Size of a subscript or superscript relative to the text around it.
pub const SCRIPT_SCALE: f64 = 0.75;

/// The runs of `s`: text on the baseline and the contents of each `_{…}` and `^{…}`.
pub fn spans(s: &str) -> Vec<(Shift, String)> {
    let mut out: Vec<(Shift, String)> = Vec::new();
    let mut push = |shift: Shift, t: &str| {
        if t.is_empty() {
            return;
        }
        match out.last_mut() {
            Some((sh, text)) if *sh == shift => text.push_str(t),
            _ => out.push((shift, t.to_string())),
        }
    };
    let mut rest = s;
    while !rest.is_empty() {
        let next = [("_{", Shift::Sub), ("^{", Shift::Super)]
            .into_iter()
            .filter_map(|(open, sh)| {
                let at = rest.find(open)?;
                let close = rest[at + 2..].find('}')?;
                Some((at, close, sh))
            })
            .min_by_key(|(at, _, _)| *at);
        let Some((at, close, shift)) = next else {
            push(Shift::Base, rest);
            break;
        };
        push(Shift::Base, &rest[..at]);
        push(shift, &rest[at + 2..at + 2 + close]);
        rest = &rest[at + 3 + close..];
    }
    out
}

/// `s` as read aloud, without markup: `θ_{v}^{d}` is `θvd`.
pub fn plain(s: &str) -> String {
    spans(s).into_iter().map(|(_, t)| t).collect()
}

/// The printed width of `s` in units of the text's average character width: scripts count
/// for their smaller size, combining marks for nothing.
pub fn width_in_chars(s: &str) -> f64 {
    spans(s)
        .iter()
        .map(|(shift, t)| {
            let n = t.chars().filter(|c| !is_combining(*c)).count() as f64;
            if *shift == Shift::Base {
                n
            } else {
                n * SCRIPT_SCALE
            }
        })
        .sum()
}

/// Combining diacritical marks (θ̂ is θ and U+0302): drawn over the letter before them.
fn is_combining(c: char) -> bool {
    ('\u{300}'..='\u{36f}').contains(&c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn braced_scripts_are_markup_and_bare_underscores_are_text() {
        assert_eq!(
            spans("θ_{v}^{d} reference"),
            [
                (Shift::Base, "θ".to_string()),
                (Shift::Sub, "v".to_string()),
                (Shift::Super, "d".to_string()),
                (Shift::Base, " reference".to_string()),
            ]
        );
        assert_eq!(spans("u_max_deg"), [(Shift::Base, "u_max_deg".to_string())]);
        // An unclosed brace is text.
        assert_eq!(spans("a_{b"), [(Shift::Base, "a_{b".to_string())]);
        assert_eq!(plain("δ_{a,cmd} of T_{e}/k_{t}"), "δa,cmd of Te/kt");
        assert_eq!(width_in_chars("θ̂_{v}"), 1.0 + SCRIPT_SCALE);
    }
}
