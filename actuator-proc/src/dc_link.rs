//! The DC link of the paper's Fig. 4: a diode rectifier from the supply, a DC-link capacitor
//! and a braking chopper (a switch and a resistor across the link).
//!
//! * Rectifier: the supply is an ideal DC source at the rectified no-load voltage
//!   `bldc.v_dc` (Table 2's V_app = 780 V) behind `supply_resistance_ohm`, through a diode:
//!   `i_r = max(0, (V_app − v)/R_s)`. No energy flows back to the supply. The rectifier's
//!   300 Hz ripple is not modelled (docs/model.md D28).
//! * Capacitor: `C dv/dt = i_r − i_inv − i_ch`, `i_inv` the inverter's input current.
//! * Chopper: on when `v ≥ chopper_on_v`, off when `v ≤ chopper_off_v` (hysteresis);
//!   `i_ch = v/R_ch` while on. Braking energy charges the capacitor and is dumped in R_ch.
//! * Auxiliary load: the drive's own consumers on the link (control electronics, gate drivers,
//!   fan, the capacitor's discharge resistor) as a resistance that draws `aux_power_w` at the
//!   supply voltage, `i_aux = g_aux v` with g_aux = P_aux/V_app² (docs/model.md D46).
//! * Over-voltage trip: above `overvoltage_trip_v` the inverter's gates are blocked (the drive
//!   in `bldc.rs` acts on [`DcLink::overvoltage`]).

use serde::{Deserialize, Serialize};

use tiltsim_protocol::settings::Checker;

/// DC-link parameters (scenario `[actuator.dc_link]`); reasons for the defaults in
/// docs/model.md D28.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DcLinkParams {
    /// DC-link capacitance C (F).
    pub capacitance_f: f64,
    /// Supply (line and transformer) resistance seen by the rectifier, R_s (Ω).
    pub supply_resistance_ohm: f64,
    /// Chopper switch-on voltage (V).
    pub chopper_on_v: f64,
    /// Chopper switch-off voltage (V), below `chopper_on_v`.
    pub chopper_off_v: f64,
    /// Braking resistor R_ch (Ω).
    pub chopper_resistance_ohm: f64,
    /// Link voltage above which the inverter's gates are blocked (V).
    pub overvoltage_trip_v: f64,
    /// Power the auxiliary load draws at the supply voltage `bldc.v_dc` (W); a resistance,
    /// so it draws P_aux (v/V_app)² at link voltage v. 0: none.
    pub aux_power_w: f64,
}

impl Default for DcLinkParams {
    fn default() -> Self {
        DcLinkParams {
            capacitance_f: 2.2e-3,
            supply_resistance_ohm: 0.1,
            chopper_on_v: 850.0,
            chopper_off_v: 830.0,
            chopper_resistance_ohm: 10.0,
            overvoltage_trip_v: 950.0,
            aux_power_w: AUX_POWER_W,
        }
    }
}

/// The auxiliary load by default (W at 780 V; docs/model.md D46).
pub const AUX_POWER_W: f64 = 100.0;

impl DcLinkParams {
    /// The auxiliary load's conductance g_aux = P_aux/V_app² (S) on a supply of `v_supply`.
    pub fn aux_conductance(&self, v_supply: f64) -> f64 {
        self.aux_power_w / (v_supply * v_supply)
    }

    /// Checks every field against the supply's no-load voltage `v_supply` (V).
    pub fn validate(&self, c: &mut Checker, v_supply: f64) {
        c.range("dc_link.capacitance_f", self.capacitance_f, 1e-5, 1.0, "F");
        c.range(
            "dc_link.supply_resistance_ohm",
            self.supply_resistance_ohm,
            1e-3,
            100.0,
            "Ω",
        );
        c.range(
            "dc_link.chopper_resistance_ohm",
            self.chopper_resistance_ohm,
            0.1,
            1e4,
            "Ω",
        );
        c.require(
            self.chopper_on_v > v_supply && self.chopper_on_v < self.overvoltage_trip_v,
            "dc_link.chopper_on_v",
            self.chopper_on_v,
            &format!(
                "a voltage above the supply's bldc.v_dc = {v_supply} V and below \
                 dc_link.overvoltage_trip_v = {} V",
                self.overvoltage_trip_v
            ),
        );
        c.require(
            self.chopper_off_v >= v_supply && self.chopper_off_v < self.chopper_on_v,
            "dc_link.chopper_off_v",
            self.chopper_off_v,
            &format!(
                "a voltage in [bldc.v_dc = {v_supply} V, dc_link.chopper_on_v = {} V)",
                self.chopper_on_v
            ),
        );
        c.range("dc_link.aux_power_w", self.aux_power_w, 0.0, 1e5, "W");
        c.range(
            "dc_link.overvoltage_trip_v",
            self.overvoltage_trip_v,
            v_supply,
            10.0 * v_supply,
            "V",
        );
    }
}

/// Energy through the link since the start (J).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LinkEnergy {
    /// Delivered into the link by the rectifier, ∫ v i_r dt.
    pub rectifier: f64,
    /// Dumped in the braking resistor, ∫ v i_ch dt.
    pub chopper: f64,
    /// Drawn by the inverter, ∫ v i_inv dt.
    pub inverter: f64,
    /// Drawn by the auxiliary load, ∫ v i_aux dt.
    pub aux: f64,
}

/// The DC link's state.
#[derive(Debug, Clone)]
pub struct DcLink {
    pub(crate) p: DcLinkParams,
    pub(crate) v_supply: f64,
    /// The auxiliary load's conductance (S).
    pub(crate) g_aux: f64,
    /// Link voltage v (V).
    pub v: f64,
    /// Chopper switch state.
    pub chopper_on: bool,
    /// Energy account.
    pub energy: LinkEnergy,
}

impl DcLink {
    /// A link charged to the supply's no-load voltage `v_supply` (V).
    pub fn new(p: &DcLinkParams, v_supply: f64) -> Self {
        DcLink {
            p: p.clone(),
            v_supply,
            g_aux: p.aux_conductance(v_supply),
            v: v_supply,
            chopper_on: false,
            energy: LinkEnergy::default(),
        }
    }

    /// Energy in the capacitor, ½ C v² (J).
    pub fn stored(&self) -> f64 {
        0.5 * self.p.capacitance_f * self.v * self.v
    }

    /// Whether the link is above its over-voltage trip level.
    #[inline]
    pub fn overvoltage(&self) -> bool {
        self.v > self.p.overvoltage_trip_v
    }

    /// One step of `dt` with the inverter drawing power `p_inv` (W, negative when braking);
    /// returns the chopper's power (W). Energy is booked on the step's mean voltage, so the
    /// account of the capacitor closes exactly: ½C(v₁² − v₀²) = C v̄ (v₁ − v₀).
    #[inline]
    pub fn step(&mut self, dt: f64, p_inv: f64) -> f64 {
        let v0 = self.v;
        if v0 >= self.p.chopper_on_v {
            self.chopper_on = true;
        } else if v0 <= self.p.chopper_off_v {
            self.chopper_on = false;
        }
        let i_r = ((self.v_supply - v0) / self.p.supply_resistance_ohm).max(0.0);
        let i_ch = if self.chopper_on {
            v0 / self.p.chopper_resistance_ohm
        } else {
            0.0
        };
        let i_inv = p_inv / v0;
        let i_aux = self.g_aux * v0;
        let v1 = v0 + dt * (i_r - i_inv - i_ch - i_aux) / self.p.capacitance_f;
        self.v = v1;
        let vm = 0.5 * (v0 + v1);
        self.energy.rectifier += dt * vm * i_r;
        self.energy.chopper += dt * vm * i_ch;
        self.energy.inverter += dt * vm * i_inv;
        self.energy.aux += dt * vm * i_aux;
        v0 * i_ch
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_link_sits_at_the_supply_voltage() {
        let p = DcLinkParams {
            aux_power_w: 0.0,
            ..Default::default()
        };
        let mut l = DcLink::new(&p, 780.0);
        for _ in 0..10_000 {
            assert_eq!(l.step(1e-6, 0.0), 0.0);
        }
        assert_eq!(l.v, 780.0);
        // With the auxiliary load the supply resistance and the load divide the voltage,
        // v = V_app/(1 + R_s g_aux), and the load draws g_aux v² (closed form; the link's
        // time constant R_s C = 0.22 ms has decayed 45 times over within 10 ms).
        let p = DcLinkParams::default();
        let mut l = DcLink::new(&p, 780.0);
        for _ in 0..10_000 {
            l.step(1e-6, 0.0);
        }
        let g = p.aux_conductance(780.0);
        let v = 780.0 / (1.0 + p.supply_resistance_ohm * g);
        assert!((l.v - v).abs() < 1e-9, "{} vs {v}", l.v);
        let drawn = l.energy.aux / 0.01;
        assert!((drawn - g * v * v).abs() < 1e-3 * g * v * v, "{drawn} W");
        assert!((g * 780.0 * 780.0 - AUX_POWER_W).abs() < 1e-9);
    }

    #[test]
    fn motoring_sags_by_the_supply_resistance_and_braking_is_dumped() {
        let p = DcLinkParams::default();
        let mut l = DcLink::new(&p, 780.0);
        // 39 kW drawn: steady state v = 780 − R i with i = P/v + g_aux v: i ≈ 50.4 A, sag
        // ≈ 5.0 V.
        for _ in 0..20_000 {
            l.step(1e-6, 39e3);
        }
        let i = 39e3 / l.v + p.aux_conductance(780.0) * l.v;
        assert!((l.v - (780.0 - 0.1 * i)).abs() < 1e-3, "{}", l.v);
        // 50 kW returned: the rectifier blocks, the capacitor charges to the chopper's
        // threshold and the chopper cycles between 830 and 850 V, dumping what comes back.
        let mut l = DcLink::new(&p, 780.0);
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for k in 0..200_000 {
            l.step(1e-6, -50e3);
            if k > 20_000 {
                lo = lo.min(l.v);
                hi = hi.max(l.v);
            }
        }
        assert!(lo > 829.0 && hi < 851.0, "{lo}..{hi}");
        assert_eq!(l.energy.rectifier, 0.0);
        let returned = -l.energy.inverter;
        let stored = l.stored() - 0.5 * p.capacitance_f * 780.0 * 780.0;
        assert!(l.energy.aux > 0.0);
        assert!(
            (returned - l.energy.chopper - l.energy.aux - stored).abs() < 1e-9 * returned,
            "{returned} vs {} + {} + {stored}",
            l.energy.chopper,
            l.energy.aux
        );
    }
}
