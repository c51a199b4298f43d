//! The cells' sources: interphase and wall heat and mass transfer from the closures, linearised
//! in the cell unknowns with the wall temperature eliminated, at the old state (step 1) and at
//! the provisional state (step 2).

use nalgebra::Vector4;

use super::{BLEND_RELAXATION_S, Scheme, StepInput, Work, liquid_share, present};
use crate::closures::{presence, smooth_step, smooth_step_slope};
use crate::cryo;
use crate::fluids::Phase;
use crate::model::{GRAVITY, State};

impl Scheme<'_> {
    /// Sources of every cell at the old state (the momentum predictor needs their Γ): the
    /// interphase and wall heat and mass transfer linearised in the cell unknowns, into
    /// `w.sources`, and each cell's new wetted fraction, into `w.wetted`.
    ///
    /// The closures' part that does not depend on the step's length ([`OldCell`]) is kept for
    /// the next attempt from the same state (`Work::old_cells`, emptied for another state): a
    /// rejected step's retry evaluates only what its shorter step changes.
    pub(super) fn old_time_sources(&self, st: &StepInput, w: &mut Work) {
        if w.old_cells.is_empty() {
            for i in 0..st.n {
                let cell = self.old_cell(st.s, i);
                w.old_cells.push(cell);
            }
        }
        for i in 0..st.n {
            let entering = entering_liquid_temperature(st, i);
            let (src, wetted) = self.sources(st.s, i, st.dt, entering, &w.old_cells[i]);
            w.sources[i] = src;
            w.wetted[i] = wetted;
        }
    }

    /// Sources at the provisional state, into `w.gamma_used`, `w.sg_used`, `w.sl_used`; the
    /// phase change of a cell marked in `w.limited` held so that at most
    /// `HELD_PHASE_CHANGE_FRACTION` of the phase it takes, as the cell held it at the old time,
    /// goes in one step.
    ///
    /// The phase-change parts of the two energy sources add up to nothing, so the scaling
    /// keeps energy.
    pub(super) fn provisional_sources(&self, st: &StepInput, w: &mut Work) {
        let (s, dt) = (st.s, st.dt);
        for i in 0..st.n {
            let (src, x) = (&w.sources[i], &w.x[i]);
            let gam = src.gamma.eval(x);
            let (available, take) = if gam < 0.0 { (s.m_g[i], -gam * dt) } else { (s.m_l[i], gam * dt) };
            let most = HELD_PHASE_CHANGE_FRACTION * available.max(0.0);
            let f = if w.limited[i] && take > most { most / take } else { 1.0 };
            w.gamma_used[i] = f * gam;
            w.sg_used[i] = src.s_g.eval(x) - (1.0 - f) * src.pc_g.eval(x);
            w.sl_used[i] = src.s_l.eval(x) - (1.0 - f) * src.pc_l.eval(x);
        }
    }

    /// Marks in `w.limited` the cells whose phase change, as the mass solve just took it
    /// (`w.gamma_used`, `w.mass_g`, `w.mass_l`), took more than `HELD_PHASE_CHANGE_FRACTION` of
    /// what the cell held of the phase over the step (its new mass plus what changed phase);
    /// returns whether there are any. Holding a cell's phase change leaves more of that phase
    /// to flow on downstream, so the masses solved again deplete no other cell.
    ///
    /// Decision: the phase change is limited only where it would take a vanishing phase
    /// (condensing vapour traces in subcooled liquid under a pressure rise, say), counted
    /// with what flows into the cell over the step. Before, every cell's phase change was
    /// held to 90 % of the phase the cell held at the old time. Mist entering a cell behind
    /// the front and evaporating within about a step was then held back by a tenth; the liquid
    /// kept the heat of the rest, crossed its table's top and flashed there, in nearly every
    /// step of the exit cells; and the mass moved at the held rate while the momentum
    /// equations exchanged the mist's momentum at the step's linearised one, which lost kinetic
    /// energy in every step with a held cell, more the longer the step (nitrogen saturated at
    /// 2.5 atm: an energy balance residual of −908 J at the default control, +5 J with steps of
    /// at most 0.05 s; +25 J at either now). It also cut the nitrogen runs' steps by 21–46 %:
    /// the flash's volume held the exit cells' steps through the volume-error check.
    pub(super) fn mark_limited(&self, st: &StepInput, w: &mut Work) -> bool {
        let mut any = false;
        for i in 0..st.n {
            let gam = w.gamma_used[i];
            let (new, take) = if gam < 0.0 { (w.mass_g[i], -gam * st.dt) } else { (w.mass_l[i], gam * st.dt) };
            if take > 0.0 && take > HELD_PHASE_CHANGE_FRACTION * (new + take) {
                w.limited[i] = true;
                any = true;
            }
        }
        any
    }

    /// The closures' view of cell `i` at the old time level.
    pub(super) fn local(&self, s: &State, i: usize) -> cryo::Local {
        let g = &self.grid;
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let sat = s.sat[i];
        cryo::Local {
            p: s.p[i],
            t_w: s.t_w[i],
            t_g: s.t_g[i],
            t_l: s.t_l[i],
            t_sat: if sat.h_lg > 0.0 { sat.t_sat } else { s.t_l[i] },
            alpha: s.alpha[i],
            rho_g: gp.rho,
            rho_l: lp.rho,
            mu_g: gp.mu,
            mu_l: lp.mu,
            k_g: gp.k,
            k_l: lp.k,
            cp_g: gp.cp,
            cp_l: lp.cp,
            h_lg: sat.h_lg,
            sigma: sat.sigma,
            h_l: lp.h,
            h_g: gp.h,
            h_l_sat: sat.h_l,
            h_g_sat: sat.h_g,
            v_g: 0.5 * (s.v_g[i] + s.v_g[i + 1]),
            v_l: 0.5 * (s.v_l[i] + s.v_l[i + 1]),
            d_h: g.d_h[i],
            gravity: if self.physics.gravity { GRAVITY } else { 0.0 },
            beta_g: -gp.drho_dt / gp.rho,
            beta_l: -lp.drho_dt / lp.rho,
            // the cell's saturation densities; the vapour bases of the boiling correlations are
            // read from the table only where the wall boils ([`cryo::Local::with_boiling_basis`]
            // in `sources`): elsewhere only the saturated vapour density is used
            rho_l_sat: if sat.h_lg > 0.0 { sat.rho_l } else { lp.rho },
            vap_sat: cryo::Vapour {
                rho: if sat.h_lg > 0.0 { sat.rho_g } else { gp.rho },
                mu: gp.mu,
                k: gp.k,
                cp: gp.cp,
            },
            vap_film: cryo::Vapour { rho: gp.rho, mu: gp.mu, k: gp.k, cp: gp.cp },
            vap_mfb: cryo::Vapour { rho: gp.rho, mu: gp.mu, k: gp.k, cp: gp.cp },
        }
    }

    /// Linearised sources of cell `i` (interphase and wall heat and mass transfer, wall
    /// temperature eliminated implicitly), and the cell's new wetted-wall fraction: the wall's
    /// coupling ([`Scheme::wall_coupling`]), then the phase change between the phases and at the
    /// wall ([`Scheme::phase_change_sources`]) or, without one, a plain exchange of heat
    /// ([`Scheme::exchange_sources`]).
    fn sources(&self, s: &State, i: usize, dt: f64, entering_t_l: f64, old: &OldCell) -> (Sources, f64) {
        let ph = &self.physics;
        let a = s.alpha[i];
        let pres_g = presence(a, ph.cryo.blend_min, ph.cryo.blend_max);
        let pres_l = presence(liquid_share(s, i), ph.cryo.blend_min, ph.cryo.blend_max);
        let (gas_here, liq_here) = (old.gas_here, old.liq_here);
        let tg = Lin::var(s.t_g[i], 2);
        let tl = Lin::var(s.t_l[i], 3);
        let cell = CellView { s, i, dt, old, gas_here, liq_here, pres_g, pres_l, tg, tl, entering_t_l };
        let (wall, wetted) = self.wall_coupling(&cell);
        let sources = match &old.interphase {
            Some(iph) => self.phase_change_sources(&cell, &wall, iph),
            None => self.exchange_sources(&cell, &wall),
        };
        (sources, wetted)
    }

    /// The closures of cell `i` at the old state `s` that do not depend on the step's length
    /// ([`OldCell`]).
    fn old_cell(&self, s: &State, i: usize) -> OldCell {
        let ph = &self.physics;
        let cp = &ph.cryo;
        let gas_here = present(s.m_g[i], s.m_l[i]);
        let liq_here = present(s.m_l[i], s.m_g[i]);
        let sat = s.sat[i];
        let has_sat = sat.h_lg > 0.0;
        let mut local = self.local(s, i);
        if liq_here && has_sat && ph.wall_heat_transfer && ph.fixed_wall_htc.is_none() {
            local = local.with_boiling_basis(self.fluid);
        }
        let regime = cryo::flow_regime(&local, cp, s.wall_heat_flux[i]);
        // The wetted fraction relaxes towards its regime value (`wall_coupling`), never below
        // the perimeter the liquid covers by geometry alone.
        let w_eq = if liq_here { cryo::wetted_fraction(&local, &regime) } else { 0.0 };
        let w_geometric =
            if liq_here { cryo::stratified_half_angle(1.0 - s.alpha[i]) / std::f64::consts::PI } else { 0.0 };
        let wall = (ph.wall_heat_transfer && ph.fixed_wall_htc.is_none())
            .then(|| cryo::WallHeatBasis::new(&local, cp, ph.correlations, &regime));
        // Liquid above its saturation temperature flashes even where no vapour is left
        // (cryo::flashing_htc: bubbles nucleate): the vapour it makes starts the gas phase.
        let flashing = liq_here && has_sat && s.t_l[i] > sat.t_sat;
        let interphase = (ph.phase_change && has_sat && liq_here && (gas_here || flashing)).then(|| {
            if ph.interphase_heat_transfer {
                cryo::interphase_heat(&local, cp, &regime)
            } else {
                cryo::Interphase { h_ig: 0.0, h_il: 0.0 }
            }
        });
        OldCell { local, gas_here, liq_here, w_eq, w_geometric, wall, interphase }
    }

    /// The wall's heat to the gas and the liquid and from the ambient, linear in the cell
    /// unknowns with the wall's new temperature eliminated, and the cell's new wetted fraction.
    fn wall_coupling(&self, cell: &CellView) -> (WallCoupling, f64) {
        let (g, ph, s, i, dt) = (&self.grid, &self.physics, cell.s, cell.i, cell.dt);
        let cp = &ph.cryo;
        let local = &cell.old.local;
        let a = s.alpha[i];
        let b = 1.0 - a;
        let v = g.volume[i];
        let (gas_here, liq_here, tg, tl) = (cell.gas_here, cell.liq_here, cell.tg, cell.tl);
        // The wetted fraction relaxes to its regime value with the time constant tauw, but never
        // below the perimeter the liquid covers by geometry alone: a pool in the bottom of the
        // tube touches δ/π of the wall at once (film boiling under it is the boiling curve's
        // business). Decision: tauw is the time of the wetting *dynamics* (spreading into a film,
        // drying); without the floor, a large tauw keeps the wall of a cell that has filled with
        // liquid heating only the few per cent of vapour left in it, which is not physical and
        // drives the cell to runaway pressures.
        let (w_eq, w_geometric) = (cell.old.w_eq, cell.old.w_geometric);
        let wetted =
            (w_eq + (s.wetted[i] - w_eq) * (-dt / cp.wetting_time_constant.max(1e-9)).exp()).max(w_geometric.min(w_eq));
        // wall heat transfer coefficients per unit fluid volume
        let per_vol = g.perimeter[i] / g.area_cell[i];
        let (hw_g, hw_l, boiling) = if ph.wall_heat_transfer {
            // the closures' basis wherever no fixed coefficient stands in (`old_cell`)
            match &cell.old.wall {
                Some(basis) => {
                    let wh = basis.at(wetted);
                    (wh.h_wg * per_vol, wh.h_wl * per_vol, wh.boiling_fraction)
                }
                None => {
                    let h = ph.fixed_wall_htc.unwrap_or(0.0);
                    (h * per_vol * a, h * per_vol * b, 0.0)
                }
            }
        } else {
            (0.0, 0.0, 0.0)
        };
        let hw_g = if gas_here { hw_g } else { 0.0 };
        let hw_l = if liq_here { hw_l } else { 0.0 };
        let h_amb = ph.ambient_htc_w_m2k * g.outer_area[i] / v;
        let c_w = g.wall_mass[i] * g.material.table().cp(s.t_w[i]) / v;
        let tw = s.t_w[i];
        // the gas exchanges heat with the wall at its recovery temperature (closure set only; a
        // fixed coefficient is the plain h (T_w − T_g) of the verification problems)
        let rec = if ph.fixed_wall_htc.is_none() { cryo::recovery_temperature_rise(local) } else { 0.0 };
        let t_gw = tg.add(Lin::constant(rec));
        let den = c_w / dt + hw_g + hw_l + h_amb;
        let a0 =
            (-hw_g * (tw - s.t_g[i] - rec) - hw_l * (tw - s.t_l[i]) + h_amb * (ph.ambient_temperature_k - tw)) / den;
        let t_w_new = Lin { c0: tw + a0, c: [0.0, 0.0, hw_g / den, hw_l / den] };
        let q_wg = t_w_new.sub(t_gw).scale(hw_g);
        let q_wl = t_w_new.sub(tl).scale(hw_l);
        let q_amb = Lin::constant(h_amb * ph.ambient_temperature_k).sub(t_w_new.scale(h_amb));
        let q_wall = q_wg.add(q_wl);
        (WallCoupling { q_wg, q_wl, q_amb, q_wall, boiling }, wetted)
    }

    /// The sources of a cell with phase change: evaporation at the wall and heat and mass
    /// transfer at the interface, each limited by the mass of the phase it takes from.
    fn phase_change_sources(&self, cell: &CellView, wall: &WallCoupling, iph: &cryo::Interphase) -> Sources {
        let (ph, s, i, dt) = (&self.physics, cell.s, cell.i, cell.dt);
        let cp = &ph.cryo;
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let sat = s.sat[i];
        let (tg, tl) = (cell.tg, cell.tl);
        let mut s_g = wall.q_wg;
        let mut s_l = wall.q_wl;
        // wall evaporation (paper: Γ_wg = q_wl/(H*_g − H*_l), scaled by Gwsc): the boiling
        // share of the wall heat to the liquid turns liquid at its own enthalpy into
        // saturated vapour; the liquid keeps q_wl − Γ_w h_g,sat, the vapour gains Γ_w h_g,sat
        let dh_w = (sat.h_g - lp.h).max(1e-3 * sat.h_lg);
        let gwsc = wall_evaporation_scale(cp.wall_mass_transfer_scale, s.t_l[i] - sat.t_sat);
        let mut g_w = wall.q_wl.scale(gwsc * wall.boiling / dh_w);
        if g_w.c0 > 0.0 {
            g_w = g_w.scale(mass_limit(g_w.c0, s.m_l[i], dt));
        }
        s_l = s_l.sub(g_w.scale(sat.h_g));
        s_g = s_g.add(g_w.scale(sat.h_g));
        // interface: Γ_ig = −(q_ig + q_il)/(h*_g − h*_l), Gisc scaling the exchange
        let scale = cp.interface_mass_transfer_scale;
        let ts = Lin { c0: sat.t_sat, c: [sat.dt_sat_dp, 0.0, 0.0, 0.0] };
        // Vapour below its saturation temperature is metastable and condenses on the liquid
        // within milliseconds: it is relaxed to T_sat with BLEND_RELAXATION_S, fully from
        // 1 K of subcooling on (RELAP5 does the same with a large gas-side coefficient).
        // Decision: the closures' interface areas (drops, films) are made for superheated
        // vapour; without this, vapour expanded in a pressure swing of a liquid-filled cell
        // cooled 15–20 K below saturation, towards the end of its property table.
        //
        // Decision: the relaxation is Newton-linearised in the subcooling u = T_sat − T_g. Its
        // coefficient H S(u) (H = m_g c_p/τ) taken at the old u (Picard) maps the old
        // subcooling to the new one with the slope −d ln S/d ln u, about −2 near saturation,
        // at steps hundreds of times τ: the choked saturated NBS tails' exit vapour swung by
        // ±0.4 K about 0.4 K of subcooling with a period of four steps. The heat H S(u) u is
        // linearised with its full slope H (S + S′ u); the extra H S′ u acts on the change of u.
        let subcooling = sat.t_sat - s.t_g[i];
        let relax = s.m_g[i].max(0.0) * gp.cp / BLEND_RELAXATION_S;
        let subcooled_gas = smooth_step(subcooling) * relax;
        let subcooled_slope = smooth_step_slope(subcooling) * relax * subcooling;
        let h_ig = scale * iph.h_ig + blend(cell.pres_g, s.m_g[i], gp.cp) + subcooled_gas;
        let h_il = scale * iph.h_il
            + blend(cell.pres_l, s.m_l[i], lp.cp)
            + self.superheat_limit_htc(s, i, sat.t_sat, cell.entering_t_l);
        let q_sum = h_ig * (sat.t_sat - s.t_g[i]) + h_il * (sat.t_sat - s.t_l[i]);
        let (hg_star, hl_star) = if q_sum <= 0.0 { (sat.h_g, lp.h) } else { (gp.h, sat.h_l) };
        let dh = (hg_star - hl_star).max(1e-3 * sat.h_lg);
        // evaporation at the liquid's new volume fraction (`evaporating_share`); condensation
        // limited by the vapour's mass (`mass_limit`), both sides scaled alike so that the
        // interface's energy balance holds
        let rate = -q_sum / dh;
        let (share, f) = if rate > 0.0 {
            (evaporating_share(s.alpha[i]), 1.0)
        } else {
            (Lin::constant(1.0), mass_limit(rate, s.m_g[i], dt))
        };
        let gas_subcooling = ts.sub(tg);
        let subcooling_change = gas_subcooling.sub(Lin::constant(subcooling));
        let q_ig = gas_subcooling.scale(h_ig).add(subcooling_change.scale(subcooled_slope)).scale(f).mul(share);
        let q_il = ts.sub(tl).scale(f * h_il).mul(share);
        // (h*: RELAP5's switch — vapour forms at saturation from liquid at its own enthalpy,
        // condenses from vapour at its own enthalpy into saturated liquid)
        let g_ig = q_ig.add(q_il).scale(-1.0 / dh);
        s_g = s_g.add(q_ig).add(g_ig.scale(hg_star));
        s_l = s_l.add(q_il).sub(g_ig.scale(hl_star));
        let gamma = g_ig.add(g_w);
        // backward Euler for the liquid's depletion by its interface alone, Γ/(1 + Γ Δt/m_l),
        // which is what the linear share gives a cell without flow
        let interface_step =
            if rate > 0.0 && s.m_l[i] > 0.0 { g_ig.c0 / (1.0 + g_ig.c0 * dt / s.m_l[i]) } else { g_ig.c0 };
        let momentum_gamma = interface_step + g_w.c0;
        let pc_g = q_ig.add(g_ig.scale(hg_star)).add(g_w.scale(sat.h_g));
        let pc_l = q_il.sub(g_ig.scale(hl_star)).sub(g_w.scale(sat.h_g));
        Sources { gamma, momentum_gamma, s_g, s_l, q_wall: wall.q_wall, q_amb: wall.q_amb, pc_g, pc_l }
    }

    /// The sources of a cell without phase change: the wall's heat and a plain exchange of heat
    /// between the phases (with the phase-blending pull of a disappearing phase).
    fn exchange_sources(&self, cell: &CellView, wall: &WallCoupling) -> Sources {
        let (ph, s, i) = (&self.physics, cell.s, cell.i);
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let a = s.alpha[i];
        let b = 1.0 - a;
        let mut s_g = wall.q_wg;
        let mut s_l = wall.q_wl;
        let h_exchange = if ph.interphase_heat_transfer { ph.interphase_htc_w_m3k * a * b } else { 0.0 };
        let h_blend = blend(cell.pres_g, s.m_g[i], gp.cp) + blend(cell.pres_l, s.m_l[i], lp.cp);
        let q = cell.tl.sub(cell.tg).scale(h_exchange + h_blend);
        s_g = s_g.add(q);
        s_l = s_l.sub(q);
        let (gamma, pc_g, pc_l) = (Lin::default(), Lin::default(), Lin::default());
        Sources { gamma, momentum_gamma: 0.0, s_g, s_l, q_wall: wall.q_wall, q_amb: wall.q_amb, pc_g, pc_l }
    }
}

/// What the closures give for cell `i` at the old state, shared by the parts of its sources.
#[derive(Debug, Clone, Copy)]
struct CellView<'a> {
    s: &'a State,
    i: usize,
    dt: f64,
    /// The closures at the old state.
    old: &'a OldCell,
    /// Whether the gas and the liquid are present ([`present`]).
    gas_here: bool,
    /// See `gas_here`.
    liq_here: bool,
    /// The phase-blending presence weights of the gas (by volume) and the liquid (by mass).
    pres_g: f64,
    /// See `pres_g`.
    pres_l: f64,
    /// The gas and liquid temperatures as functions of the cell unknowns.
    tg: Lin,
    /// See `tg`.
    tl: Lin,
    /// The highest temperature of the liquid the old velocities carry into the cell
    /// ([`entering_liquid_temperature`]), K; −∞ where none enters.
    entering_t_l: f64,
}

/// The wall's heat per unit fluid volume, linear in the cell unknowns, W/m³.
#[derive(Debug, Clone, Copy)]
struct WallCoupling {
    /// Wall to gas.
    q_wg: Lin,
    /// Wall to liquid.
    q_wl: Lin,
    /// Ambient to wall.
    q_amb: Lin,
    /// Wall to fluid, `q_wg + q_wl`.
    q_wall: Lin,
    /// The boiling share of the heat to the liquid.
    boiling: f64,
}

/// The heat transfer coefficient, W/(m³ K), with which a disappearing phase (presence weight
/// `pres`, mass `m` per unit volume, heat capacity `cp`) is pulled to the continuous phase's
/// temperature.
fn blend(pres: f64, m: f64, cp: f64) -> f64 {
    (1.0 - pres) * m.max(0.0) * cp / BLEND_RELAXATION_S
}

/// The factor on a transfer `rate` (kg/m³/s) out of a phase of which `available` kg/m³ are
/// left: a phase cannot give more mass than it has. Where a step of `dt` would condense (or the
/// wall evaporate) more than half of what is left of a vanishing phase, the transfer is scaled
/// down so that it empties over a few steps instead of going negative (a smaller step would do
/// the same; this saves the hundreds of thousands of steps a trace of condensing vapour in
/// subcooled liquid otherwise costs). The cap moves with the step length; the interface's
/// evaporation is implicit instead ([`evaporating_share`]).
fn mass_limit(rate: f64, available: f64, dt: f64) -> f64 {
    let take = rate.abs() * dt;
    if take > 0.5 * available { 0.5 * available / take } else { 1.0 }
}

/// The evaporating interface's heat and mass transfer as a share of its old-time value, linear
/// in the cell unknowns: the liquid's volume fraction at the new time over the old one,
/// φ = (1 − α − δα)/(1 − α). The transfer is φ times the interface's old-time coefficients
/// times the linearised temperature differences ([`Lin::mul`]).
///
/// Decision: the interface of evaporating liquid that is going (the drops of a mist) is
/// proportional to its volume fraction, so its transfer is taken at the new fraction: with the
/// liquid's mass balance this is backward Euler for its depletion, which empties it
/// geometrically at any step and never below zero, with the liquid that flows in during the
/// step evaporating too. Before, a transfer that would take more than half of the liquid's mass
/// in one step was scaled down to that half (`mass_limit`, which still limits condensation);
/// the cap ignored the liquid flowing in and moved the results with the step length. The mist
/// leaving the subcooled 4.2 atm NBS line (2 m exit cell, gas at 150–180 m/s, 0.065 kg/m³ of
/// drops, each crossing the cell in 13 ms) was evaporated at 3–5 % of its interface transfer at
/// the 28–44 ms steps the run takes there and at all of it with steps of 2.5 ms: with long steps
/// the drops left the line superheated to their table's end (100 K at 1.2 bar, against 87 K),
/// the line's flow from 60 to 160 s was 5 % lower and the station-4 chilldown 2.4 s later
/// (mean of nine one-ulp neighbours, 163.21 s against 160.83 s with `time.max_dt_s = 0.0025`;
/// now 162.35 s against 161.65 s). Nitrogen saturated at 11 atm on the envelope's line chills
/// at 84.0 s, where it took 84.18 s only with 10 ms steps before (85.5 s at the default steps;
/// `the_exit_mist_evaporates_alike_at_any_step` in `tests/envelope_regressions.rs`).
///
/// Condensation keeps the cap: taken at the vapour's new fraction as well (an experiment), a
/// trace of vapour in subcooled liquid collapses within the step at the inlet of a subcooled
/// line, and the liquid hammer of each collapse holds the steps to the pressure rule: 2.75 times
/// the steps on the subcooled NBS run and 39 % more step attempts over the envelope
/// (2026-11-29, VALIDATION.md "Time-step refinement"), for a station-4 chilldown that no longer
/// moves with the step (159.28 s at the default steps, 159.86 s at 2.5 ms). That is the next
/// step-dependent part.
fn evaporating_share(alpha: f64) -> Lin {
    let mut phi = Lin::constant(1.0);
    let liquid = 1.0 - alpha;
    if liquid > 0.0 {
        phi.c[1] = -1.0 / liquid;
    }
    phi
}

/// Linear function of the cell unknowns (δp, δα, δT_g, δT_l): c0 + c·x.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Lin {
    pub(super) c0: f64,
    pub(super) c: [f64; 4],
}

impl Lin {
    fn constant(c0: f64) -> Self {
        Self { c0, c: [0.0; 4] }
    }
    fn var(base: f64, k: usize) -> Self {
        let mut c = [0.0; 4];
        c[k] = 1.0;
        Self { c0: base, c }
    }
    fn scale(self, s: f64) -> Self {
        Self { c0: self.c0 * s, c: self.c.map(|v| v * s) }
    }
    fn add(self, o: Self) -> Self {
        let mut c = self.c;
        for (a, b) in c.iter_mut().zip(o.c) {
            *a += b;
        }
        Self { c0: self.c0 + o.c0, c }
    }
    fn sub(self, o: Self) -> Self {
        self.add(o.scale(-1.0))
    }
    /// The product of two linear functions to first order in the unknowns (Newton's
    /// linearisation: the product of their changes is dropped).
    fn mul(self, o: Self) -> Self {
        let mut c = [0.0; 4];
        for (k, ck) in c.iter_mut().enumerate() {
            *ck = self.c0 * o.c[k] + o.c0 * self.c[k];
        }
        Self { c0: self.c0 * o.c0, c }
    }
    pub(super) fn eval(&self, x: &Vector4<f64>) -> f64 {
        self.c0 + self.c[0] * x[0] + self.c[1] * x[1] + self.c[2] * x[2] + self.c[3] * x[3]
    }
}

/// Per-cell source terms, linear in the cell unknowns.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sources {
    /// Vapour generation Γ_g (interface + wall), kg/m³/s.
    pub(super) gamma: Lin,
    /// The step's Γ_g as the momentum predictor takes it, before the pressure solve: `gamma`'s
    /// old-time value with the evaporating interface's part depleted over the step as the
    /// cell's liquid alone would be ([`evaporating_share`]), kg/m³/s.
    pub(super) momentum_gamma: f64,
    /// Gas energy source, W/m³.
    pub(super) s_g: Lin,
    /// Liquid energy source, W/m³.
    pub(super) s_l: Lin,
    /// Wall-to-fluid heat, W/m³.
    pub(super) q_wall: Lin,
    /// Ambient-to-wall heat per fluid volume, W/m³.
    pub(super) q_amb: Lin,
    /// The phase-change parts of `s_g` and `s_l` (interface heat with its mass transfer, and
    /// the wall evaporation), which add up to nothing: scaled together with `gamma` when a
    /// vanishing phase would otherwise give more mass than it has.
    pub(super) pc_g: Lin,
    /// See `pc_g`.
    pub(super) pc_l: Lin,
}

/// The factor on the wall's boiling heat that turns into evaporation: `Gwsc` where the physics
/// allows it, at a liquid superheat `superheat_k` = T_l − T_sat.
///
/// Decision: the paper scales Γ_wg = Gwsc q_wl/(H*_g − H*_l) as a whole. With Gwsc > 1 the
/// evaporated liquid takes more latent heat than the wall's boiling heat supplies; the
/// difference, (Gwsc − 1) q_b, comes out of the liquid's own sensible heat. Liquid can give that
/// only while it is superheated: liquid below its saturation temperature does not evaporate into
/// its own vapour at the cell's pressure. Without a limit, wall boiling with Gwsc = 3 cooled
/// subcooled liquid at twice the wall's heat rate down to the triple point, where the run ended
/// (87 of the 94 failures of the 1000-sample robustness study). So the part of Gwsc above 1
/// acts in full from [`WALL_EVAPORATION_SUPERHEAT_K`] of superheat and fades out to none at
/// saturation. Gwsc ≤ 1, and so the defaults and the NBS calibration, are unchanged.
fn wall_evaporation_scale(gwsc: f64, superheat_k: f64) -> f64 {
    if gwsc <= 1.0 { gwsc } else { 1.0 + (gwsc - 1.0) * smooth_step(superheat_k / WALL_EVAPORATION_SUPERHEAT_K) }
}

/// The fraction of the phase it takes that a cell's phase change may take in one step where
/// it would take more ([`Scheme::mark_limited`], [`Scheme::provisional_sources`]).
const HELD_PHASE_CHANGE_FRACTION: f64 = 0.9;

/// Liquid superheat from which the wall's evaporation takes its full `Gwsc` above 1, K.
const WALL_EVAPORATION_SUPERHEAT_K: f64 = 1.0;

/// Share of the way from T_sat to the liquid table's end at which superheated liquid starts to
/// flash by nucleation throughout ([`Scheme::superheat_limit_htc`]).
const SUPERHEAT_LIMIT_ONSET: f64 = 0.5;
/// Share of the way at which that flashing acts in full.
const SUPERHEAT_LIMIT_FULL: f64 = 0.9;

impl Scheme<'_> {
    /// Heat transfer coefficient per unit volume, W/(m³ K), that flashes liquid superheated
    /// towards the end of its metastable table within [`BLEND_RELAXATION_S`]; `entering_t_l` is
    /// the hottest liquid flowing into the cell ([`entering_liquid_temperature`]).
    ///
    /// Decision: liquid superheated far beyond saturation does not wait for the closures'
    /// bubbles (their interface area is made for ordinary boiling): near its superheat limit it
    /// nucleates throughout and flashes within milliseconds, the liquid counterpart of the
    /// relaxation of subcooled vapour. The relaxation starts halfway from T_sat to the table's
    /// last liquid temperature at the cell's pressure (the metastable end, where du/dT|p has
    /// risen tenfold towards the spinodal) and acts in full from 90 % of the way. Before, with a
    /// low `Gwsc` most of the wall's boiling heat stayed in the liquid, which superheated by
    /// 19 K at 5 bar until it left the table and the run ended. Liquid less superheated than
    /// half the way is not touched.
    ///
    /// Decision: the way is measured on the liquid entering the cell as well as on the cell's
    /// own, and the farther of the two counts. Liquid that arrives past halfway to its limit at
    /// the cell's pressure flashes as it enters, and the cell's liquid, which it stirs, is held
    /// at saturation with it. Measured on the cell's liquid alone, the relaxation switched on
    /// and off on alternate steps where such liquid flowed in steadily: a step that began with
    /// the cell's liquid near saturation did not flash it, the inflow carried it past its
    /// table's end (recovered at the edge), the next step flashed it all back to saturation,
    /// and so on. Para-hydrogen saturated at 11 atm entering the NBS line's inlet cell at
    /// 10 atm (`examples/nbs/calibrated-six-drops.toml`, the envelope's slowest run) flipped that way at
    /// every step of its 260 s of steady flow after the chilldown, the cell's pressure between
    /// 1.0066 and 1.0427 MPa, and its volume errors held the steps at 3.4 ms (BENCHMARKS.md,
    /// "Flashing inflow").
    fn superheat_limit_htc(&self, s: &State, i: usize, t_sat: f64, entering_t_l: f64) -> f64 {
        let superheat = (s.t_l[i] - t_sat).max(entering_t_l - t_sat);
        if superheat <= 0.0 {
            return 0.0;
        }
        let Some((_, t_end)) = self.fluid.phase_temperature_range(Phase::Liquid, s.p[i]) else { return 0.0 };
        if t_end <= t_sat {
            return 0.0;
        }
        let reach = superheat / (t_end - t_sat);
        let weight = smooth_step((reach - SUPERHEAT_LIMIT_ONSET) / (SUPERHEAT_LIMIT_FULL - SUPERHEAT_LIMIT_ONSET));
        if weight > 0.0 { weight * s.m_l[i].max(0.0) * s.liquid[i].cp / BLEND_RELAXATION_S } else { 0.0 }
    }
}

/// The highest temperature of the liquid that the old velocities carry into cell `i`: through
/// each face where the liquid moves into the cell, the temperature of the liquid on the other
/// side (the neighbouring cell's, or the boundary's where the face is the line's end), if
/// liquid is there; −∞ where no liquid enters.
fn entering_liquid_temperature(st: &StepInput, i: usize) -> f64 {
    let s = st.s;
    // each face: whether the liquid moves into the cell through it, the cell beyond it (none at
    // the line's end) and the boundary there
    let faces = [
        (s.v_l[i] > 0.0, i.checked_sub(1), st.inlet0),
        (s.v_l[i + 1] < 0.0, (i + 1 < st.n).then_some(i + 1), st.outlet0),
    ];
    faces
        .into_iter()
        .filter(|&(entering, _, _)| entering)
        .filter_map(|(_, beyond, boundary)| match beyond {
            Some(k) => present(s.m_l[k], s.m_g[k]).then_some(s.t_l[k]),
            None => (boundary.alpha < 1.0).then_some(boundary.t_l),
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// What the closures give for a cell at the old state whatever the step's length: the
/// closures' view of the cell (with the boiling bases where the wall boils), which phases are
/// present, the equilibrium and geometric floor of its wetted fraction (from its flow regime),
/// the wall's heat transfer before the wetted fraction is set ([`cryo::WallHeatBasis`]) and, in
/// a cell with phase change, the interface's coefficients.
#[derive(Debug, Clone, Copy)]
pub(super) struct OldCell {
    local: cryo::Local,
    /// Whether the gas and the liquid are present ([`present`]).
    gas_here: bool,
    /// See `gas_here`.
    liq_here: bool,
    w_eq: f64,
    w_geometric: f64,
    /// `None` where the wall's heat is not from the closures (none, or a fixed coefficient).
    wall: Option<cryo::WallHeatBasis>,
    /// `None` in a cell without phase change ([`Scheme::exchange_sources`]).
    interphase: Option<cryo::Interphase>,
}
