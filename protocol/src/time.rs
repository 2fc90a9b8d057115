//! Simulated time on the base-tick grid, computed one way everywhere (the plant's clock, every
//! table's `time` column, events), so that a time read from one file matches the same instant
//! in another exactly.

/// The time of tick boundary `step` on a grid of `dt` s: `step / n` when `dt` is `1/n` s for
/// a whole `n` (so 9 ms on a 1 ms grid is the double nearest to 0.009, where `9 × 0.001`
/// gives `0.009000000000000001`), `step · dt` otherwise.
pub fn tick_time(step: u64, dt: f64) -> f64 {
    let per_second = (1.0 / dt).round();
    if per_second >= 1.0 && (per_second * dt - 1.0).abs() < 1e-12 {
        step as f64 / per_second
    } else {
        step as f64 * dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_times_are_the_doubles_nearest_to_their_decimal_values() {
        // On a 1 ms grid every time reads back as the decimal it stands for: the shortest
        // form of step/1000 has at most three decimals.
        for step in 0..200_000_u64 {
            let t = tick_time(step, 1e-3);
            let want: f64 = format!("{}.{:03}", step / 1000, step % 1000)
                .parse()
                .unwrap();
            assert_eq!(t.to_bits(), want.to_bits(), "step {step}");
        }
        assert_eq!(tick_time(350, 1e-3).to_string(), "0.35");
        assert_eq!(tick_time(7, 5e-4).to_string(), "0.0035");
        // A grid that is not 1/n s is stepped by multiplication.
        assert_eq!(tick_time(3, 0.003), 3.0 * 0.003);
    }
}
