//! One time step of the nearly-implicit two-fluid scheme.
//!
//! The step follows the RELAP5-3D nearly-implicit method as the paper describes it (Sec.
//! "Algorithm"), in two steps:
//!
//! **Step 1.**
//! (a) *Provisional velocities*: the phasic momentum equations at every junction with implicit
//! convection (donor-cell v ∂v/∂x, linearised about the old velocity), implicit wall friction,
//! interphase drag (Newton-linearised in the relative velocity where it grows faster than
//! linearly), virtual mass (its time-derivative term) and form losses, with the old
//! pressure gradient: a block-tridiagonal system with 2×2 blocks over the junctions.
//! (b) *Velocity–pressure coupling*: the new velocity of a junction is its provisional velocity
//! plus a correction linear in the change of the pressure difference across it, through the
//! inverse of the junction's own 2×2 block: v = ṽ + w (δp_L − δp_R).
//! (c) *Pressure*: each cell's expanded (linearised) gas mass, liquid mass, gas energy and liquid
//! energy equations in the unknowns (δp, δα, δT_g, δT_l) — with interphase heat and mass
//! transfer and the wall heat linearised implicitly in pressure and phasic temperatures, and the
//! lumped wall temperature eliminated locally — are solved as a 4×4 system in terms of the
//! neighbouring pressure changes; the first row gives a tridiagonal pressure equation.
//! (d) Back-substitution gives the new velocities, provisional void fraction and temperatures,
//! and provisional interphase and wall heat and mass transfer.
//!
//! **Step 2.** The unexpanded (conservative) phasic mass and energy equations with the new
//! velocities, new-time donor-cell fluxes and the provisional sources: four independent
//! tridiagonal systems. Mass is conserved to round-off. The wall energy changes by exactly the
//! heat the fluid received. The state then follows from the conserved masses and energies at the
//! new pressure; the mismatch between the two phases' volumes and the cell volume (the volume
//! error) is carried into the next step's pressure equation, which drives it back to zero.
//!
//! Primary thermodynamic variables are pressure and phasic temperatures (see
//! [`crate::fluids`]); the primary conserved variables are the phasic masses and internal
//! energies per unit volume.

// Index loops over cells and junctions mirror the discrete equations (i, j ± 1) one to one.
#![allow(clippy::needless_range_loop)]

use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};

use crate::case::BoundaryKind;
use crate::closures::{presence, smooth_step};
use crate::cryo;
use crate::fluids::{FluidTable, Phase, PhaseProps, Saturation};
use crate::linalg;
use crate::model::{BoundaryState, GRAVITY, Grid, State, clamp_to_phase};

/// Physics switches and the constants of the basic closures.
#[derive(Debug, Clone, PartialEq)]
pub struct Physics {
    /// Interphase and wall mass transfer.
    pub phase_change: bool,
    /// Wall–fluid heat transfer.
    pub wall_heat_transfer: bool,
    /// Heat transfer between the phases.
    pub interphase_heat_transfer: bool,
    /// Interfacial drag.
    pub interphase_drag: bool,
    /// Wall friction.
    pub wall_friction: bool,
    /// Gravity.
    pub gravity: bool,
    /// Virtual mass.
    pub virtual_mass: bool,
    /// Fixed wall heat transfer coefficient, W/(m² K), instead of correlations.
    pub fixed_wall_htc: Option<f64>,
    /// Volumetric interphase heat transfer coefficient scale, W/(m³ K), times α(1 − α).
    pub interphase_htc_w_m3k: f64,
    /// Ambient temperature, K.
    pub ambient_temperature_k: f64,
    /// Ambient heat transfer coefficient on the outer wall, W/(m² K).
    pub ambient_htc_w_m2k: f64,
    /// The cryogenic closure constants (from the parameter registry).
    pub cryo: cryo::CryoParams,
    /// Which film-boiling / rewet correlation set.
    pub correlations: cryo::CorrelationSet,
}

impl Default for Physics {
    fn default() -> Self {
        Self {
            phase_change: true,
            wall_heat_transfer: true,
            interphase_heat_transfer: true,
            interphase_drag: true,
            wall_friction: true,
            gravity: true,
            virtual_mass: true,
            fixed_wall_htc: None,
            interphase_htc_w_m3k: 1.0e5,
            ambient_temperature_k: 290.0,
            ambient_htc_w_m2k: 0.0,
            cryo: cryo::CryoParams::default(),
            correlations: cryo::CorrelationSet::Paper,
        }
    }
}

/// Why a step was rejected (the driver halves the time step and retries).
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// Cell (or junction) index.
    pub cell: usize,
    /// Which variable.
    pub variable: &'static str,
    /// Its value.
    pub value: f64,
    /// Why.
    pub reason: &'static str,
}

/// Budget terms of one step (SI, integrated over the step and the line).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepBudget {
    /// Mass entering through the inlet junction, kg (negative: leaving).
    pub mass_in: f64,
    /// Mass leaving through the outlet junction, kg (negative: entering).
    pub mass_out: f64,
    /// Internal-energy flux in at the inlet minus out at the outlet, J.
    pub energy_flux: f64,
    /// Pressure work terms of the phasic energy equations, J.
    pub pressure_work: f64,
    /// Heat from the wall into the fluid, J.
    pub wall_heat: f64,
    /// Heat from the ambient into the wall, J.
    pub ambient_heat: f64,
    /// Kinetic energy the momentum equations turned into heat (friction, form losses, drag and
    /// the donor-cell convection's numerical dissipation), J.
    pub dissipation: f64,
    /// Energy added by state adjustments outside the balance equations (vanishing-phase
    /// resets and clamps), J, net.
    pub adjustment: f64,
    /// The same adjustments' magnitudes, summed, J.
    pub adjustment_abs: f64,
    /// Magnitude of the kinetic and potential energy carried through the boundaries, J (the
    /// scale of the energy balance where no heat moves).
    pub mechanical_flux_abs: f64,
    /// Total-energy (h + v²/2 + g z) inflow minus outflow through the boundaries, J.
    pub total_energy_flux: f64,
}

impl StepBudget {
    /// Books an adjustment of `joules` made outside the balance equations.
    fn adjust(&mut self, joules: f64) {
        self.adjustment += joules;
        self.adjustment_abs += joules.abs();
    }
}

/// What a step produced besides the new state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepReport {
    /// Largest change of a controlled variable as a fraction of its allowed change (≤ 1).
    pub change_ratio: f64,
    /// Largest |volume error| over the cells.
    pub max_volume_error: f64,
    /// The controlled variable that came closest to its limit (what holds the step down).
    pub limiting: &'static str,
    /// Cell (or junction, for a velocity) of [`StepReport::limiting`].
    pub limiting_index: usize,
    /// Budget terms.
    pub budget: StepBudget,
}

/// Relative change of the relative velocity in the difference that gives the drag's Newton slope.
const NEWTON_DRAG_STEP: f64 = 0.01;

/// Largest allowed relative change per step (the paper's 25 %).
pub const MAX_RELATIVE_CHANGE: f64 = 0.25;
/// Scales below which a change is measured against the scale instead of the value, so that
/// quantities near zero do not stall the step control.
pub const SCALE_PRESSURE_PA: f64 = 2.0e4;
/// Void-fraction scale.
pub const SCALE_VOID: f64 = 0.2;
/// Temperature scale, K.
pub const SCALE_TEMPERATURE_K: f64 = 20.0;
/// Velocity scale, m/s: a velocity may change by 25 % of max(|v|, 10 m/s) in a step. Decision:
/// near a quench front the slow phase velocities (a few m/s) flicker by tens of cm/s from step
/// to step while the vapour leaves the line at 100–200 m/s; a 2 m/s floor held the NBS runs to
/// millisecond steps for no change in the result (chilldown times within 3 s at 2 and 10 m/s).
pub const SCALE_VELOCITY_M_S: f64 = 10.0;
/// Relaxation time with which a disappearing phase is pulled to the velocity and temperature of
/// the continuous one, s. A time constant rather than a multiple of 1/Δt, so that the pull does
/// not change abruptly with the step size (the step control measures changes per step).
pub const BLEND_RELAXATION_S: f64 = 1e-3;
/// Volume fraction below which a phase whose energy has left its property table is reset to
/// the other phase's temperature (see the state recovery in [`Scheme::step`]).
pub const TRACE_RESET_FRACTION: f64 = 0.1;
/// Largest pressure correction (as a fraction of the pressure) that a volume error left by a
/// step may imply for the next one.
pub const VOLUME_ERROR_PRESSURE_FRACTION: f64 = 0.02;
/// Volume fraction above which a phase's temperature and velocity enter the step control.
pub const CONTROLLED_FRACTION: f64 = 1e-2;
/// Largest volume error accepted after a step.
pub const MAX_VOLUME_ERROR: f64 = 2e-3;

/// Linear function of the cell unknowns (δp, δα, δT_g, δT_l): c0 + c·x.
#[derive(Debug, Clone, Copy, Default)]
struct Lin {
    c0: f64,
    c: [f64; 4],
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
    fn eval(&self, x: &Vector4<f64>) -> f64 {
        self.c0 + self.c[0] * x[0] + self.c[1] * x[1] + self.c[2] * x[2] + self.c[3] * x[3]
    }
}

/// Per-cell source terms, linear in the cell unknowns.
#[derive(Debug, Clone, Copy, Default)]
struct Sources {
    /// Vapour generation Γ_g (interface + wall), kg/m³/s.
    gamma: Lin,
    /// Gas energy source, W/m³.
    s_g: Lin,
    /// Liquid energy source, W/m³.
    s_l: Lin,
    /// Wall-to-fluid heat, W/m³.
    q_wall: Lin,
    /// Ambient-to-wall heat per fluid volume, W/m³.
    q_amb: Lin,
    /// The phase-change parts of `s_g` and `s_l` (interface heat with its mass transfer, and
    /// the wall evaporation), which add up to nothing: scaled together with `gamma` when a
    /// vanishing phase would otherwise give more mass than it has.
    pc_g: Lin,
    /// See `pc_g`.
    pc_l: Lin,
}

/// Reusable work arrays of the scheme.
#[derive(Debug, Clone, Default)]
struct Work {
    /// Per junction: the coefficients of step 1's forces, for the work they do.
    mech: Vec<JunctionWork>,
    /// Per junction: the gas and liquid fractions of the momentum equations' pressure force
    /// (none where the velocities are prescribed).
    alpha_mom: Vec<Option<(f64, f64)>>,
    /// Per cell: the pressure work of the momentum equations that the energy equations' flow
    /// work did not book, J (taken from the cell's internal energy).
    work_fix: Vec<f64>,
    wetted: Vec<f64>,
    /// Dissipated heat per cell going to the gas and the liquid, W (with the old velocities in
    /// step 1, with the work of the implicit forces in step 2).
    heat_g: Vec<f64>,
    heat_l: Vec<f64>,
    dp: Vec<f64>,
    mass_g: Vec<f64>,
    mass_l: Vec<f64>,
    dvol_g: Vec<f64>,
    dvol_l: Vec<f64>,
    gamma_used: Vec<f64>,
    sg_used: Vec<f64>,
    sl_used: Vec<f64>,
    reset: Vec<bool>,
    /// Per junction: the heat its momentum forces put into the fluid, W/m³ ([`booked_heat`]).
    junction_heat: Vec<f64>,
    vt_g: Vec<f64>,
    vt_l: Vec<f64>,
    w_g: Vec<f64>,
    w_l: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    d: Vec<f64>,
    s: Vec<f64>,
    lower: Vec<Matrix2<f64>>,
    diag: Vec<Matrix2<f64>>,
    upper: Vec<Matrix2<f64>>,
    rhs2: Vec<Vector2<f64>>,
    scratch2: Vec<Matrix2<f64>>,
    minv: Vec<Matrix4<f64>>,
    r4: Vec<Vector4<f64>>,
    cl: Vec<Vector4<f64>>,
    cr: Vec<Vector4<f64>>,
    sources: Vec<Sources>,
    x: Vec<Vector4<f64>>,
}

/// The nearly-implicit scheme bound to a fluid, a grid and physics.
#[derive(Debug, Clone)]
pub struct Scheme<'a> {
    /// Property table.
    pub fluid: &'a FluidTable,
    /// Geometry.
    pub grid: Grid,
    /// Switches and closure constants.
    pub physics: Physics,
    work: Work,
}

/// The donor (upwind) side of a junction for a given velocity.
#[inline]
fn upwind<T: Copy>(v: f64, left: T, right: T) -> T {
    if v >= 0.0 { left } else { right }
}

impl<'a> Scheme<'a> {
    /// A scheme for `grid` with the given fluid and physics.
    pub fn new(fluid: &'a FluidTable, grid: Grid, physics: Physics) -> Self {
        Self { fluid, grid, physics, work: Work::default() }
    }

    /// Advances `s` by `dt` with boundary states at the old (`b0`) and new (`b1`) time.
    /// Returns the new state, or the reason the step must be retried with a smaller `dt`.
    pub fn step(
        &mut self,
        s: &State,
        dt: f64,
        b0: [&BoundaryState; 2],
        b1: [&BoundaryState; 2],
    ) -> Result<(State, StepReport), Rejection> {
        let n = self.grid.n;
        let nj = n + 1;
        let mut w = std::mem::take(&mut self.work);
        resize(&mut w, n);
        let result = self.step_inner(s, dt, b0, b1, &mut w, n, nj);
        self.work = w;
        result
    }

    #[allow(clippy::too_many_arguments)]
    fn step_inner(
        &self,
        s: &State,
        dt: f64,
        b0: [&BoundaryState; 2],
        b1: [&BoundaryState; 2],
        w: &mut Work,
        n: usize,
        nj: usize,
    ) -> Result<(State, StepReport), Rejection> {
        let g = &self.grid;
        let ph = &self.physics;
        let fluid = self.fluid;
        let grav = if ph.gravity { GRAVITY } else { 0.0 };
        let (inlet0, outlet0) = (b0[0], b0[1]);
        let (inlet1, outlet1) = (b1[0], b1[1]);
        let prescribed = |j: usize| -> Option<(f64, f64)> {
            let b = if j == 0 {
                Some(inlet1)
            } else if j == n {
                Some(outlet1)
            } else {
                None
            }?;
            match b.kind {
                BoundaryKind::Velocity => Some((b.v_g, b.v_l)),
                BoundaryKind::Closed => Some((0.0, 0.0)),
                _ => None,
            }
        };

        // ---- Sources of every cell at the old state (the momentum step needs their Γ) ----
        for i in 0..n {
            let (src, wetted) = self.sources(s, i, dt);
            w.sources[i] = src;
            w.wetted[i] = wetted;
        }

        // ---- Step 1a: provisional velocities (block-tridiagonal, 2×2 blocks) ----
        for j in 0..nj {
            w.lower[j] = Matrix2::zeros();
            w.upper[j] = Matrix2::zeros();
            if let Some((vg, vl)) = prescribed(j) {
                w.mech[j] = JunctionWork::default();
                w.alpha_mom[j] = None;
                w.diag[j] = Matrix2::identity();
                w.rhs2[j] = Vector2::new(vg, vl);
                continue;
            }
            let jc = self.junction_coefficients(s, j, inlet0, outlet0, grav);
            let (vg, vl) = (s.v_g[j], s.v_l[j]);
            let dxj = g.dx_junction(j);
            // Momentum of the mass that changes phase: the paper's A Γ_g u_i in the vapour's
            // conservative momentum equation and −A Γ_g u_i in the liquid's, which in the
            // non-conservative form here are Γ_g (v_I − v_g) and −Γ_g (v_I − v_l). With the
            // interface velocity v_I = (v_g + v_l)/2 (RELAP5's choice) both are −(Γ/2)(v_g − v_l),
            // the same force on both phases: evaporating liquid leaves at v_I > v_l, so the liquid
            // that stays slows down, and the vapour that forms at v_I < v_g slows the vapour.
            // Decision: v_I the mean, because then the kinetic energy of the two phases changes
            // only by the work of the other forces (−(Γ/2)(v_g² − v_l²) of work against the
            // ½ Γ (v_g² − v_l²) the transferred mass carries); any other v_I dissipates or creates
            // kinetic energy that the energy equations do not see. Γ is the old-time rate of
            // the junction's cells (the mean of the two; a boundary junction's one cell). Each
            // part is implicit where it damps its own phase's velocity and explicit where it
            // drives it (for evaporation the liquid's own −(Γ/2)(−v_l), for condensation the
            // vapour's). Before, the liquid's term had the drag's sign (+(Γ/2)(v_g − v_l)),
            // which created Γ (v_g − v_l) v_l of kinetic energy.
            let gamma_j = {
                let cell_gamma = |i: usize| w.sources[i].gamma.c0;
                match (j == 0, j == n) {
                    (true, _) => cell_gamma(0),
                    (_, true) => cell_gamma(n - 1),
                    _ => 0.5 * (cell_gamma(j - 1) + cell_gamma(j)),
                }
            };
            let mt = if ph.phase_change && gamma_j.is_finite() { 0.5 * gamma_j } else { 0.0 };
            let drag = jc.drag;
            let mut diag = Matrix2::new(
                jc.ar_g / dt + jc.fric_g + drag + jc.vm / dt,
                -drag - jc.vm / dt,
                -drag - jc.vm / dt,
                jc.ar_l / dt + jc.fric_l + drag + jc.vm / dt,
            );
            let mut rhs = Vector2::new(
                jc.ar_g * vg / dt + jc.vm / dt * (vg - vl) - jc.a_g * jc.dp_old / dxj
                    + jc.ar_g * jc.gx
                    + jc.drag_explicit,
                jc.ar_l * vl / dt - jc.vm / dt * (vg - vl) - jc.a_l * jc.dp_old / dxj + jc.ar_l * jc.gx
                    - jc.drag_explicit,
            );
            // both phases feel −(Γ/2)(v_g − v_l): each part implicit where it damps its own
            // phase's velocity, explicit where it would drive it
            if mt > 0.0 {
                diag[(0, 0)] += mt;
                diag[(0, 1)] -= mt;
                diag[(1, 0)] += mt;
                rhs[1] += mt * vl;
            } else if mt < 0.0 {
                let c = -mt;
                diag[(1, 1)] += c;
                diag[(1, 0)] -= c;
                diag[(0, 1)] += c;
                rhs[0] += c * vg;
            }
            // Implicit donor-cell convection v^n (v_j − v_up)^{n+1} / dx. Out of a reservoir the
            // fluid starts from rest, and the jump from 0 to v is given its Bernoulli value
            // ½ ρ v² (the donor-cell form would give ρ v²).
            // Where the flow area changes between two junctions, the velocity jump is the
            // area ratio and ½ (v_j + v_up) (v_j − v_up) is the Bernoulli ½ Δ(v²) exactly.
            // (the standard donor-cell terms are kept for the heat they dissipate, see
            // [`booked_heat`]; the Bernoulli forms dissipate nothing)
            let mut work = JunctionWork {
                fric: [jc.fric_g, jc.fric_l],
                drag: jc.drag,
                drag_explicit: jc.drag_explicit,
                conv: [None; 2],
            };
            for (k, (v, ar)) in [(vg, jc.ar_g), (vl, jc.ar_l)].into_iter().enumerate() {
                let old_v = |jj: usize| if k == 0 { s.v_g[jj] } else { s.v_l[jj] };
                let upstream = if v >= 0.0 { j.checked_sub(1) } else { (j < n).then_some(j + 1) };
                match upstream {
                    Some(up) => {
                        let c = if g.area_junction[up] != g.area_junction[j] {
                            ar * (0.5 * (v + old_v(up))).abs() / dxj
                        } else {
                            let c = ar * v.abs() / dxj;
                            // (a phase at rest carries no kinetic energy through the term)
                            work.conv[k] = (c > 0.0).then_some((c, up));
                            c
                        };
                        diag[(k, k)] += c;
                        if up < j {
                            w.lower[j][(k, k)] -= c;
                        } else {
                            w.upper[j][(k, k)] -= c;
                        }
                    }
                    // out of a reservoir; other boundaries carry the junction's own velocity
                    // (no convective acceleration)
                    None => {
                        let b = if v >= 0.0 { inlet0 } else { outlet0 };
                        if b.kind == BoundaryKind::Reservoir {
                            diag[(k, k)] += 0.5 * ar * v.abs() / dxj;
                        }
                    }
                }
            }
            w.mech[j] = work;
            w.alpha_mom[j] = Some((jc.a_g, jc.a_l));
            w.diag[j] = diag;
            w.rhs2[j] = rhs;
        }
        // the pressure-correction weights use each junction's own block (before the solve
        // overwrites the right-hand sides)
        for j in 0..nj {
            if prescribed(j).is_some() {
                w.w_g[j] = 0.0;
                w.w_l[j] = 0.0;
                continue;
            }
            let (a_g, a_l) = self.junction_alpha(s, j, inlet0, outlet0);
            let dxj = g.dx_junction(j);
            let Some(inv) = w.diag[j].try_inverse() else {
                return Err(Rejection { cell: j, variable: "momentum", value: dt, reason: "singular junction block" });
            };
            let wv = inv * Vector2::new(a_g / dxj, a_l / dxj);
            w.w_g[j] = wv[0];
            w.w_l[j] = wv[1];
        }
        if !linalg::block_tridiagonal(&w.lower, &w.diag, &w.upper, &mut w.rhs2, &mut w.scratch2) {
            return Err(Rejection { cell: 0, variable: "velocity", value: dt, reason: "momentum system singular" });
        }
        for j in 0..nj {
            w.vt_g[j] = w.rhs2[j][0];
            w.vt_l[j] = w.rhs2[j][1];
        }
        // the pressure equation's estimate of the heat of the step: the same work with the
        // provisional velocities and the old masses (step 2 books it with the new ones; the
        // closer the two, the smaller the volume error the difference leaves)
        let mass = [s.m_g.as_slice(), s.m_l.as_slice()];
        for j in 0..nj {
            let vt = [w.vt_g.as_slice(), w.vt_l.as_slice()];
            w.junction_heat[j] = booked_heat(&w.mech[j], j, vt, vt, mass, g.dx_junction(j));
        }

        // ---- Step 1c: per-cell 4×4 systems → tridiagonal pressure equation ----
        let dp_in = inlet1.p - inlet0.p;
        let dp_out = outlet1.p - outlet0.p;
        for i in 0..n {
            let v = g.volume[i];
            let (gp, lp) = (&s.gas[i], &s.liquid[i]);
            let a = s.alpha[i];
            let b = 1.0 - a;
            let src = w.sources[i];
            let mut m = Matrix4::zeros();
            let mut r = Vector4::zeros();
            let mut cl = Vector4::zeros();
            let mut cr = Vector4::zeros();
            // storage terms
            m[(0, 0)] = a * gp.drho_dp;
            m[(0, 1)] = gp.rho;
            m[(0, 2)] = a * gp.drho_dt;
            m[(1, 0)] = b * lp.drho_dp;
            m[(1, 1)] = -lp.rho;
            m[(1, 3)] = b * lp.drho_dt;
            m[(2, 0)] = a * (gp.u * gp.drho_dp + gp.rho * gp.du_dp);
            m[(2, 1)] = gp.rho * gp.h;
            m[(2, 2)] = a * (gp.u * gp.drho_dt + gp.rho * gp.du_dt);
            m[(3, 0)] = b * (lp.u * lp.drho_dp + lp.rho * lp.du_dp);
            m[(3, 1)] = -lp.rho * lp.h;
            m[(3, 3)] = b * (lp.u * lp.drho_dt + lp.rho * lp.du_dt);
            // Old-time residuals: the volume-error correction. In a cell nearly full of liquid a
            // small volume error is a large pressure change (liquid is stiff), so at most the
            // part of the error worth VOLUME_ERROR_PRESSURE_FRACTION of the pressure is corrected
            // per step; the rest is corrected over the following steps.
            let kappa = a * gp.drho_dp / gp.rho + b * lp.drho_dp / lp.rho;
            let implied = s.volume_error[i].abs() / kappa.max(1e-300);
            let limit = VOLUME_ERROR_PRESSURE_FRACTION * s.p[i].max(SCALE_PRESSURE_PA);
            let lambda = if implied > limit { limit / implied } else { 1.0 };
            r[0] = lambda * (s.m_g[i] - a * gp.rho);
            r[1] = lambda * (s.m_l[i] - b * lp.rho);
            r[2] = lambda * (s.e_g[i] - a * gp.rho * gp.u);
            r[3] = lambda * (s.e_l[i] - b * lp.rho * lp.u);
            // frictional dissipation (from the old velocities; step 2 adds the same heat)
            let (heat_g, heat_l) = self.dissipation_split(s, &w.junction_heat, i);
            w.heat_g[i] = heat_g;
            w.heat_l[i] = heat_l;
            r[2] += dt * heat_g / v;
            r[3] += dt * heat_l / v;
            // sources: row += −dt * source (moved to the left)
            for (row, lin, sign) in [(0, src.gamma, 1.0), (1, src.gamma, -1.0), (2, src.s_g, 1.0), (3, src.s_l, 1.0)] {
                r[row] += sign * dt * lin.c0;
                for k in 0..4 {
                    m[(row, k)] -= sign * dt * lin.c[k];
                }
            }
            // fluxes through the left (j = i) and right (j = i + 1) junctions
            for (j, side) in [(i, -1.0), (i + 1, 1.0)] {
                let area = g.area_junction[j] * self.open_fraction(j, inlet1, outlet1);
                let f = dt * area / v;
                let (ml, mr) = self.donor_pair(s, j, inlet0, outlet0);
                for (k, (vt, wj)) in [(w.vt_g[j], w.w_g[j]), (w.vt_l[j], w.w_l[j])].into_iter().enumerate() {
                    let d = upwind(vt, ml, mr);
                    let (mass, energy, frac) = if k == 0 { (d.m_g, d.e_g, d.a_g) } else { (d.m_l, d.e_l, d.a_l) };
                    let p_work = s.p[i];
                    // rows: mass k, energy k (2 + k)
                    for (row, q) in [(k, mass), (2 + k, energy + p_work * frac)] {
                        // side * f * q * (vt + wj (δp_L − δp_R))
                        r[row] -= side * f * q * vt;
                        let c = side * f * q * wj;
                        if side > 0.0 {
                            // right junction: δp_L = δp_i, δp_R = δp_{i+1}
                            m[(row, 0)] += c;
                            cr[row] -= c;
                        } else {
                            // left junction: δp_L = δp_{i-1}, δp_R = δp_i
                            m[(row, 0)] -= c;
                            cl[row] += c;
                        }
                    }
                }
            }
            // An absent phase has no energy equation: its temperature follows the other phase
            // (within its own table), so that it enters well defined if it flows in.
            for (present, row, col, phase) in [
                (present(s.m_g[i], s.m_l[i]), 2usize, 2usize, Phase::Gas),
                (present(s.m_l[i], s.m_g[i]), 3, 3, Phase::Liquid),
            ] {
                if !present {
                    let target = match phase {
                        Phase::Gas => clamp_to_phase(fluid, Phase::Gas, s.p[i], s.t_l[i]) - s.t_g[i],
                        Phase::Liquid => clamp_to_phase(fluid, Phase::Liquid, s.p[i], s.t_g[i]) - s.t_l[i],
                    };
                    for k in 0..4 {
                        m[(row, k)] = 0.0;
                    }
                    m[(row, col)] = 1.0;
                    r[row] = target;
                    cl[row] = 0.0;
                    cr[row] = 0.0;
                }
            }
            let Some(minv) = m.try_inverse() else {
                return Err(Rejection { cell: i, variable: "cell", value: a, reason: "singular cell system" });
            };
            w.minv[i] = minv;
            w.r4[i] = r;
            w.cl[i] = cl;
            w.cr[i] = cr;
            let sol_r = minv * r;
            let sol_l = minv * cl;
            let sol_rr = minv * cr;
            w.a[i] = sol_l[0];
            w.b[i] = 1.0;
            w.c[i] = sol_rr[0];
            w.d[i] = sol_r[0];
        }
        // boundary pressure changes are known
        if !matches!(inlet1.kind, BoundaryKind::Velocity | BoundaryKind::Closed) {
            w.d[0] -= w.a[0] * dp_in;
        }
        if !matches!(outlet1.kind, BoundaryKind::Velocity | BoundaryKind::Closed) {
            w.d[n - 1] -= w.c[n - 1] * dp_out;
        }
        if !linalg::tridiagonal(&w.a, &w.b, &w.c, &mut w.d, &mut w.s) {
            return Err(Rejection { cell: 0, variable: "pressure", value: dt, reason: "pressure system singular" });
        }
        let dp_at = |i: isize, d: &[f64]| -> f64 {
            if i < 0 {
                dp_in
            } else if i as usize >= n {
                dp_out
            } else {
                d[i as usize]
            }
        };
        for i in 0..n {
            let dpl = dp_at(i as isize - 1, &w.d);
            let dpr = dp_at(i as isize + 1, &w.d);
            w.x[i] = w.minv[i] * (w.r4[i] - w.cl[i] * dpl - w.cr[i] * dpr);
        }
        // new velocities
        let mut next = s.clone();
        for (d, x) in w.dp.iter_mut().zip(&w.x) {
            *d = x[0];
        }
        let dps = &w.dp;
        for j in 0..nj {
            let dpl = dp_at(j as isize - 1, dps);
            let dpr = dp_at(j as isize, dps);
            next.v_g[j] = w.vt_g[j] + w.w_g[j] * (dpl - dpr);
            next.v_l[j] = w.vt_l[j] + w.w_l[j] * (dpl - dpr);
        }

        // ---- Step 2: conservative mass and energy, new-time donors ----
        let mut budget = StepBudget::default();

        // Sources at the provisional state. The linearised phase change, evaluated there, may
        // take more of a vanishing phase than the cell holds (condensing vapour traces in
        // subcooled liquid under a pressure rise, say): then all of the cell's phase change is
        // scaled down so that at most 90 % of that phase goes in one step. The phase-change
        // parts of the two energy sources add up to nothing, so the scaling keeps energy.
        for i in 0..n {
            let (src, x) = (&w.sources[i], &w.x[i]);
            let gam = src.gamma.eval(x);
            let (available, take) = if gam < 0.0 { (s.m_g[i], -gam * dt) } else { (s.m_l[i], gam * dt) };
            let f = if take > 0.9 * available.max(0.0) { 0.9 * available.max(0.0) / take } else { 1.0 };
            w.gamma_used[i] = f * gam;
            w.sg_used[i] = src.s_g.eval(x) - (1.0 - f) * src.pc_g.eval(x);
            w.sl_used[i] = src.s_l.eval(x) - (1.0 - f) * src.pc_l.eval(x);
        }
        for phase in Phase::ALL {
            let gas = phase == Phase::Gas;
            let vel: &[f64] = if gas { &next.v_g } else { &next.v_l };
            self.transport_matrix(w, vel, dt, inlet1, outlet1);
            let (bin, bout) = (inlet1, outlet1);
            let (in_m, _, _) = boundary_conserved(bin, gas);
            let (out_m, _, _) = boundary_conserved(bout, gas);
            // mass
            for i in 0..n {
                let v = g.volume[i];
                let old = if gas { s.m_g[i] } else { s.m_l[i] };
                let gamma = w.gamma_used[i];
                w.d[i] = v * old + v * dt * if gas { gamma } else { -gamma };
            }
            let a0 = g.area_junction[0] * self.open_fraction(0, inlet1, outlet1);
            let an = g.area_junction[n] * self.open_fraction(n, inlet1, outlet1);
            if vel[0] > 0.0 {
                w.d[0] += dt * vel[0] * a0 * in_m;
            }
            if vel[n] < 0.0 {
                w.d[n - 1] -= dt * vel[n] * an * out_m;
            }
            if !linalg::tridiagonal(&w.a, &w.b, &w.c, &mut w.d, &mut w.s) {
                return Err(Rejection { cell: 0, variable: "mass", value: dt, reason: "mass system singular" });
            }
            if gas {
                w.mass_g.copy_from_slice(&w.d);
            } else {
                w.mass_l.copy_from_slice(&w.d);
            }
            let masses: &[f64] = if gas { &w.mass_g } else { &w.mass_l };
            // boundary mass fluxes with the new donors
            let flux_in = dt * vel[0] * a0 * if vel[0] > 0.0 { in_m } else { masses[0] };
            let flux_out = dt * vel[n] * an * if vel[n] >= 0.0 { masses[n - 1] } else { out_m };
            budget.mass_in += flux_in;
            budget.mass_out += flux_out;
        }
        // the heat of the step: the work the momentum equations' forces did on the new
        // velocities, with the new donor masses
        let v1 = [next.v_g.as_slice(), next.v_l.as_slice()];
        for j in 0..nj {
            let vt = [w.vt_g.as_slice(), w.vt_l.as_slice()];
            let mass = [w.mass_g.as_slice(), w.mass_l.as_slice()];
            w.junction_heat[j] = booked_heat(&w.mech[j], j, v1, vt, mass, g.dx_junction(j));
        }
        for i in 0..n {
            let (heat_g, heat_l) = self.dissipation_split(s, &w.junction_heat, i);
            w.heat_g[i] = heat_g;
            w.heat_l[i] = heat_l;
        }
        // Each phase's volume change over the step, from its new mass (just solved) at its
        // provisional density, so that the p dV work matches the mass that actually moved (the
        // step-1 void fraction alone can disagree for a phase that is nearly gone).
        for i in 0..n {
            let x = &w.x[i];
            // The linearised density is held within a factor 2 of the old one: the provisional
            // temperature of a phase too small for an energy equation of its own (it follows the
            // other phase) can be 100 K away, where the tangent goes to zero or below, and a
            // trace of 10⁻¹⁰ kg/m³ was given a volume 75 times the cell's (a p dV of 10 kJ in one
            // step, which the trace reset then returned as created energy).
            let provisional = |pp: &PhaseProps, dt_k: f64| {
                (pp.rho + pp.drho_dp * x[0] + pp.drho_dt * dt_k).clamp(0.5 * pp.rho, 2.0 * pp.rho)
            };
            let rho_g = provisional(&s.gas[i], x[2]);
            let rho_l = provisional(&s.liquid[i], x[3]);
            let (a_g, a_l) = (w.mass_g[i].max(0.0) / rho_g, w.mass_l[i].max(0.0) / rho_l);
            w.dvol_g[i] = a_g - s.alpha[i];
            w.dvol_l[i] = a_l - (1.0 - s.alpha[i]);
        }
        // Work consistency. The momentum equations' pressure force α_j ∂p/∂x takes the
        // junction's mean fraction (the hydrostatics of a stratified column and a manometer's
        // interfaces need it), the energy equations' flow work the donor fraction α̂ of the volume
        // that moved; where they differ the pressure gave the flow kinetic energy (or friction
        // heat) (α_j − α̂) v A Δt (p_left − p_right) that no energy equation paid for. Decision:
        // that work is taken from the internal energy of the cells the junction joins (half each;
        // a boundary junction's one cell), shared between the phases by heat capacity like the
        // dissipation, so that the discrete kinetic plus internal energy is conserved. Without
        // it the flashing outflow of the saturated 2.5 atm run (void rising downstream) created
        // 4.7 W after its chilldown.
        let mut fix = std::mem::take(&mut w.work_fix);
        fix.iter_mut().for_each(|f| *f = 0.0);
        for j in 0..nj {
            let Some((am_g, am_l)) = w.alpha_mom[j] else { continue };
            let p_at = |i: usize| s.p[i] + w.x[i][0];
            let p_left = if j == 0 { inlet1.p } else { p_at(j - 1) };
            let p_right = if j == n { outlet1.p } else { p_at(j) };
            let area = g.area_junction[j] * self.open_fraction(j, inlet1, outlet1);
            let mut excess = 0.0;
            for (gas, vel, a_mom, dvol) in [(true, &next.v_g, am_g, &w.dvol_g), (false, &next.v_l, am_l, &w.dvol_l)] {
                let moved = self.flux_volume(s, dvol, gas, vel, j, dt, inlet1, outlet1);
                excess += (dt * vel[j] * area * a_mom - moved) * (p_left - p_right);
            }
            if !excess.is_finite() {
                continue;
            }
            match (j == 0, j == n) {
                (true, _) => fix[0] += excess,
                (_, true) => fix[n - 1] += excess,
                _ => {
                    fix[j - 1] += 0.5 * excess;
                    fix[j] += 0.5 * excess;
                }
            }
        }
        w.work_fix = fix;
        for phase in Phase::ALL {
            let gas = phase == Phase::Gas;
            let vel: &[f64] = if gas { &next.v_g } else { &next.v_l };
            self.transport_matrix(w, vel, dt, inlet1, outlet1);
            let (bin, bout) = (inlet1, outlet1);
            let (_, in_e, _) = boundary_conserved(bin, gas);
            let (_, out_e, _) = boundary_conserved(bout, gas);
            let a0 = g.area_junction[0] * self.open_fraction(0, inlet1, outlet1);
            let an = g.area_junction[n] * self.open_fraction(n, inlet1, outlet1);
            // energy
            let mut pw_total = 0.0;
            let mut dissipation = 0.0;
            let dvol_phase: &[f64] = if gas { &w.dvol_g } else { &w.dvol_l };
            let frac_flux = |j: usize| self.flux_volume(s, dvol_phase, gas, vel, j, dt, inlet1, outlet1);
            for i in 0..n {
                let v = g.volume[i];
                let old = if gas { s.e_g[i] } else { s.e_l[i] };
                let src = if gas { w.sg_used[i] } else { w.sl_used[i] };
                let dvol = if gas { w.dvol_g[i] } else { w.dvol_l[i] };
                // p^n [V Δα_k + Δt Σ(α̂_k v A)] with the new-time donor fractions of the mass
                // solve (α̂ = m^{n+1}/ρ̃, the volume the convected mass occupies). Decision: with
                // old-time donors a phase that empties from a cell in one step (vapour swept out
                // by liquid, a mist's last drops) was charged the flow work of a volume that no
                // longer left with it; its energy went to −10¹⁷ J/kg, the trace reset gave it
                // back, and 0.3 MJ of a saturated run's 3 MJ moved through resets.
                let fix = {
                    let (cg, cl) = (s.m_g[i].max(0.0) * s.gas[i].cp, s.m_l[i].max(0.0) * s.liquid[i].cp);
                    let f = if cg + cl > 0.0 { if gas { cg / (cg + cl) } else { cl / (cg + cl) } } else { 0.0 };
                    f * w.work_fix[i]
                };
                let pw = -s.p[i] * (v * dvol + frac_flux(i + 1) - frac_flux(i)) - fix;
                pw_total += pw;
                // dissipation of junction j (power per volume × junction volume) is shared by
                // the cells it lies in; a boundary junction's volume lies in its one cell
                let heat = dt * if gas { w.heat_g[i] } else { w.heat_l[i] };
                dissipation += heat;
                w.d[i] = v * old + pw + v * dt * src + heat;
            }
            if vel[0] > 0.0 {
                w.d[0] += dt * vel[0] * a0 * in_e;
            }
            if vel[n] < 0.0 {
                w.d[n - 1] -= dt * vel[n] * an * out_e;
            }
            if !linalg::tridiagonal(&w.a, &w.b, &w.c, &mut w.d, &mut w.s) {
                return Err(Rejection { cell: 0, variable: "energy", value: dt, reason: "energy system singular" });
            }
            let e_in = dt * vel[0] * a0 * if vel[0] > 0.0 { in_e } else { w.d[0] };
            let e_out = dt * vel[n] * an * if vel[n] >= 0.0 { w.d[n - 1] } else { out_e };
            budget.energy_flux += e_in - e_out;
            budget.pressure_work += pw_total;
            budget.dissipation += dissipation;
            for i in 0..n {
                if gas {
                    next.m_g[i] = w.mass_g[i];
                    next.e_g[i] = w.d[i];
                } else {
                    next.m_l[i] = w.mass_l[i];
                    next.e_l[i] = w.d[i];
                }
            }
        }

        next.wetted.copy_from_slice(&w.wetted);
        // wall energy and heat budgets
        for i in 0..n {
            let src = &w.sources[i];
            let x = &w.x[i];
            let v = g.volume[i];
            let q_wall = src.q_wall.eval(x) * v * dt;
            let q_amb = src.q_amb.eval(x) * v * dt;
            budget.wall_heat += q_wall;
            next.wall_heat_flux[i] = q_wall / (dt * g.perimeter[i] * g.dx[i]);
            budget.ambient_heat += q_amb;
            next.e_w[i] = s.e_w[i] + (q_amb - q_wall) / g.wall_mass[i];
            next.t_w[i] = g.material.table().temperature(next.e_w[i]);
        }

        // ---- new thermodynamic state from the conserved variables ----
        let mut max_verr: f64 = 0.0;
        for i in 0..n {
            let p = s.p[i] + w.x[i][0];
            if !(p.is_finite() && p > 0.0) {
                return Err(Rejection { cell: i, variable: "pressure", value: p, reason: "non-physical pressure" });
            }
            let c = fluid.constants();
            if !(p >= c.p_min_pa && p <= c.p_max_pa) {
                return Err(Rejection {
                    cell: i,
                    variable: "pressure",
                    value: p,
                    reason: "outside the property table's pressure range",
                });
            }
            next.p[i] = p;
            let total = next.m_g[i] + next.m_l[i];
            for (gas, m) in [(true, next.m_g[i]), (false, next.m_l[i])] {
                if !m.is_finite() || m < -1e-12 * total {
                    return Err(Rejection {
                        cell: i,
                        variable: if gas { "gas mass" } else { "liquid mass" },
                        value: m,
                        reason: "negative phase mass",
                    });
                }
            }
            let tiny = PRESENT_MASS_FRACTION * total.max(1e-30);
            let (mg, ml) = (next.m_g[i].max(0.0), next.m_l[i].max(0.0));
            next.m_g[i] = mg;
            next.m_l[i] = ml;
            // gas
            let tg_guess = s.t_g[i] + w.x[i][2];
            let tl_guess = s.t_l[i] + w.x[i][3];
            // A phase present in more than a trace keeps the temperature its conserved energy
            // gives. A trace (volume fraction below blend_min, or below TRACE_RESET_FRACTION
            // when its energy has left the table) takes the other phase's temperature, moved
            // into its own table: its energy per unit mass is ill-conditioned (tiny mass, finite
            // pressure work, compression by liquid hammer), and the reset moves at most a trace
            // of energy, booked as an adjustment in the budget.
            let recover = |phase: Phase, m: f64, e: f64, guess: f64, other_t: f64, budget: &mut StepBudget| {
                let (name, energy_name, what) = match phase {
                    Phase::Gas => {
                        ("gas temperature", "gas specific energy (J/kg)", "gas energy outside the property table")
                    }
                    Phase::Liquid => (
                        "liquid temperature",
                        "liquid specific energy (J/kg)",
                        "liquid energy outside the property table",
                    ),
                };
                let target = clamp_to_phase(fluid, phase, p, other_t);
                let reset = |budget: &mut StepBudget| -> Result<(f64, PhaseProps, f64, bool), Rejection> {
                    let pr = fluid.phase_props(phase, p, target).map_err(|_| Rejection {
                        cell: i,
                        variable: name,
                        value: target,
                        reason: "outside the property table",
                    })?;
                    budget.adjust((m * pr.u - e) * g.volume[i]);
                    Ok((target, pr, m * pr.u, m > tiny))
                };
                if m <= tiny {
                    return reset(budget);
                }
                // the phase's volume fraction, estimated with its old density
                let old_rho = match phase {
                    Phase::Gas => s.gas[i].rho,
                    Phase::Liquid => s.liquid[i].rho,
                };
                let trace_frac = m / old_rho;
                if trace_frac < ph.cryo.blend_min {
                    return reset(budget);
                }
                match fluid.temperature_from_energy(phase, p, e / m, guess) {
                    Ok((t, pr)) => Ok((t, pr, e, false)),
                    Err(_) if trace_frac < ph.cryo.blend_max.max(TRACE_RESET_FRACTION) => {
                        // the nearest temperature the table holds, which changes the trace's
                        // density (and so the cell's volume balance) least
                        let Some((lo, hi)) = fluid.phase_temperature_range(phase, p) else {
                            return reset(budget);
                        };
                        let u_lo = fluid.phase_props(phase, p, lo).map(|pr| pr.u).unwrap_or(f64::NAN);
                        let margin = 1e-6 * (hi - lo);
                        let t = if e / m <= u_lo { lo + margin } else { hi - margin };
                        let pr = fluid.phase_props(phase, p, t).map_err(|_| Rejection {
                            cell: i,
                            variable: name,
                            value: t,
                            reason: "outside the property table",
                        })?;
                        budget.adjust((m * pr.u - e) * g.volume[i]);
                        Ok((t, pr, m * pr.u, true))
                    }
                    // the value is the specific internal energy, J/kg (no temperature fits it)
                    Err(_) => Err(Rejection { cell: i, variable: energy_name, value: e / m, reason: what }),
                }
            };
            let (tg, gp, eg, reset_g) = recover(Phase::Gas, mg, next.e_g[i], tg_guess, tl_guess, &mut budget)?;
            let (tl, lp, el, reset_l) = recover(Phase::Liquid, ml, next.e_l[i], tl_guess, tg, &mut budget)?;
            w.reset[i] = reset_g || reset_l;
            next.e_g[i] = eg;
            next.e_l[i] = el;
            let ag = mg / gp.rho;
            let al = ml / lp.rho;
            let verr = ag + al - 1.0;
            max_verr = max_verr.max(verr.abs());
            next.alpha[i] = ag / (ag + al);
            next.t_g[i] = tg;
            next.t_l[i] = tl;
            next.gas[i] = gp;
            next.liquid[i] = lp;
            next.volume_error[i] = verr;
            next.sat[i] = saturation_or_none(fluid, p);
        }
        // total-energy boundary flux: enthalpy, kinetic and potential energy carried by the
        // boundary mass fluxes (donor properties)
        (budget.total_energy_flux, budget.mechanical_flux_abs) = self.total_energy_flux(&next, dt, inlet1, outlet1);
        next.time = s.time + dt;

        // no NaN escapes a step: anything non-finite rejects it, naming where
        let finite = |v: &[f64]| v.iter().position(|x| !x.is_finite());
        for (name, values) in [
            ("gas velocity", &next.v_g),
            ("liquid velocity", &next.v_l),
            ("wall temperature", &next.t_w),
            ("gas energy", &next.e_g),
            ("liquid energy", &next.e_l),
            ("void fraction", &next.alpha),
        ] {
            if let Some(i) = finite(values) {
                return Err(Rejection { cell: i, variable: name, value: values[i], reason: "not a finite number" });
            }
        }

        // ---- step control ----
        let mut ratio: f64 = 0.0;
        let mut worst = Rejection { cell: 0, variable: "", value: 0.0, reason: "" };
        let mut check = |cell: usize, variable: &'static str, old: f64, new: f64, scale: f64| {
            let r = (new - old).abs() / (MAX_RELATIVE_CHANGE * old.abs().max(scale));
            if r.is_nan() || r > ratio {
                ratio = if r.is_finite() { r } else { f64::INFINITY };
                worst = Rejection { cell, variable, value: new, reason: "changed by more than 25 %" };
            }
        };
        // a phase's temperature and velocity are controlled only where it fills at least
        // CONTROLLED_FRACTION of the volume (a fixed fraction, not `blend_xmax`: the step sizes,
        // and through them the results, would otherwise move with a blending threshold)
        let xmax = CONTROLLED_FRACTION;
        for i in 0..n {
            check(i, "pressure", s.p[i], next.p[i], SCALE_PRESSURE_PA);
            check(i, "void fraction", s.alpha[i], next.alpha[i], SCALE_VOID);
            if s.alpha[i].min(next.alpha[i]) > xmax {
                check(i, "gas temperature", s.t_g[i], next.t_g[i], SCALE_TEMPERATURE_K);
            }
            if (1.0 - s.alpha[i]).min(1.0 - next.alpha[i]) > xmax {
                check(i, "liquid temperature", s.t_l[i], next.t_l[i], SCALE_TEMPERATURE_K);
            }
            check(i, "wall temperature", s.t_w[i], next.t_w[i], SCALE_TEMPERATURE_K);
        }
        for j in 0..nj {
            let (fg, fl) = self.junction_min_fractions(s, j);
            let (ag, al) = self.junction_alpha(s, j, inlet0, outlet0);
            let (fg, fl) = (fg.min(ag), fl.min(al));
            if fg > xmax {
                check(j, "gas velocity", s.v_g[j], next.v_g[j], SCALE_VELOCITY_M_S);
            }
            if fl > xmax {
                check(j, "liquid velocity", s.v_l[j], next.v_l[j], SCALE_VELOCITY_M_S);
            }
        }
        if ratio > 1.0 {
            return Err(worst);
        }
        // reject a step that leaves a cell with a volume error above the limit and larger
        // than it had (an error inherited from earlier steps shrinks under the next pressure
        // solves; a smaller step cannot remove it)
        // (nor one that a trace reset made: the reset is not a function of the step size)
        // In a cell full of liquid even a small volume error is a large pressure correction in
        // the next step (liquid is stiff): the error is also limited by the pressure change it
        // implies, |e| / κ with κ the cell's volume compressibility.
        let too_big = |i: usize| {
            let (gp, lp, a) = (&next.gas[i], &next.liquid[i], next.alpha[i]);
            let kappa = a * gp.drho_dp / gp.rho + (1.0 - a) * lp.drho_dp / lp.rho;
            let e = next.volume_error[i].abs();
            e > MAX_VOLUME_ERROR || e > VOLUME_ERROR_PRESSURE_FRACTION * next.p[i].max(SCALE_PRESSURE_PA) * kappa
        };
        let grew = |i: usize| !w.reset[i] && too_big(i) && next.volume_error[i].abs() > s.volume_error[i].abs();
        if let Some(i) = (0..n)
            .filter(|&i| grew(i))
            .max_by(|&a, &b| next.volume_error[a].abs().total_cmp(&next.volume_error[b].abs()))
        {
            return Err(Rejection {
                cell: i,
                variable: "volume error",
                value: next.volume_error[i],
                reason: "phase volumes do not fill the cell",
            });
        }
        Ok((
            next,
            StepReport {
                change_ratio: ratio,
                max_volume_error: max_verr,
                limiting: worst.variable,
                limiting_index: worst.cell,
                budget,
            },
        ))
    }

    /// Dissipated power (W) that cell `i` receives from its two junctions: each junction's
    /// power per volume times its control volume, shared by the cells it lies in (a boundary
    /// junction's control volume lies wholly in its one cell).
    /// Volume of a phase carried through junction `j` over the step, m³: Δt v A α̂, α̂ the
    /// new-time donor fraction of the mass solve (the old fraction plus `dvol` of the upstream
    /// cell) or the boundary state's fraction for inflow.
    #[allow(clippy::too_many_arguments)]
    fn flux_volume(
        &self,
        s: &State,
        dvol: &[f64],
        gas: bool,
        vel: &[f64],
        j: usize,
        dt: f64,
        inlet: &BoundaryState,
        outlet: &BoundaryState,
    ) -> f64 {
        let g = &self.grid;
        let n = g.n;
        let area = g.area_junction[j] * self.open_fraction(j, inlet, outlet);
        let upstream = if vel[j] >= 0.0 { j.checked_sub(1) } else { (j < n).then_some(j) };
        let frac = match upstream {
            Some(c) => (if gas { s.alpha[c] } else { 1.0 - s.alpha[c] }) + dvol[c],
            None => {
                let b = if j == 0 { inlet } else { outlet };
                if gas { b.alpha } else { 1.0 - b.alpha }
            }
        };
        dt * vel[j] * area * frac
    }

    fn dissipation_share(&self, diss: &[f64], i: usize) -> f64 {
        let g = &self.grid;
        let share = |j: usize| -> f64 {
            let vol = g.area_junction[j] * g.dx_junction(j);
            let inside = if j == 0 || j == g.n { 1.0 } else { 0.5 };
            inside * diss[j] * vol
        };
        share(i) + share(i + 1)
    }

    /// The donor-cell transport matrix of the conservative step (the same for a phase's mass and
    /// energy): `V m_i + Δt (outflow − inflow)` with new-time donors, into `w.a`, `w.b`, `w.c`.
    fn transport_matrix(&self, w: &mut Work, vel: &[f64], dt: f64, inlet: &BoundaryState, outlet: &BoundaryState) {
        let g = &self.grid;
        for i in 0..g.n {
            let (jl, jr) = (i, i + 1);
            let al = g.area_junction[jl] * self.open_fraction(jl, inlet, outlet);
            let ar = g.area_junction[jr] * self.open_fraction(jr, inlet, outlet);
            let (vl, vr) = (vel[jl], vel[jr]);
            w.b[i] = g.volume[i] + dt * (vr.max(0.0) * ar - vl.min(0.0) * al);
            w.a[i] = -dt * vl.max(0.0) * al;
            w.c[i] = dt * vr.min(0.0) * ar;
        }
    }

    /// Cell `i`'s dissipation (W) split between gas and liquid in proportion to their heat
    /// capacities m_k c_p,k.
    fn dissipation_split(&self, s: &State, diss: &[f64], i: usize) -> (f64, f64) {
        let total = self.dissipation_share(diss, i);
        let cg = s.m_g[i].max(0.0) * s.gas[i].cp;
        let cl = s.m_l[i].max(0.0) * s.liquid[i].cp;
        if cg + cl <= 0.0 {
            return (0.0, 0.0);
        }
        let fg = cg / (cg + cl);
        (total * fg, total * (1.0 - fg))
    }

    fn open_fraction(&self, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> f64 {
        if j == 0 {
            inlet.open_fraction
        } else if j == self.grid.n {
            outlet.open_fraction
        } else {
            1.0
        }
    }

    /// Donor quantities on the two sides of junction `j` (boundary states at the ends).
    fn donor_pair(&self, s: &State, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> (Donor, Donor) {
        let n = self.grid.n;
        let cell = |i: usize| Donor {
            m_g: s.m_g[i],
            m_l: s.m_l[i],
            e_g: s.e_g[i],
            e_l: s.e_l[i],
            a_g: s.alpha[i],
            a_l: 1.0 - s.alpha[i],
        };
        let left = if j == 0 { Donor::from_boundary(inlet) } else { cell(j - 1) };
        let right = if j == n { Donor::from_boundary(outlet) } else { cell(j) };
        (left, right)
    }

    /// Junction phase fractions for the pressure-gradient term.
    fn junction_alpha(&self, s: &State, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> (f64, f64) {
        let a = self.junction_state(s, j, inlet, outlet).alpha;
        (a, 1.0 - a)
    }

    fn junction_state(&self, s: &State, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> JunctionState {
        let n = self.grid.n;
        let cell = |i: usize| JunctionState { alpha: s.alpha[i], rho_g: s.gas[i].rho, rho_l: s.liquid[i].rho };
        let bnd = |b: &BoundaryState| JunctionState { alpha: b.alpha, rho_g: b.gas.rho, rho_l: b.liquid.rho };
        if j > 0 && j < n {
            let (l, r) = (cell(j - 1), cell(j));
            let (wl, wr) = (self.grid.dx[j - 1], self.grid.dx[j]);
            let f = wl / (wl + wr);
            return JunctionState {
                alpha: f * l.alpha + (1.0 - f) * r.alpha,
                rho_g: f * l.rho_g + (1.0 - f) * r.rho_g,
                rho_l: f * l.rho_l + (1.0 - f) * r.rho_l,
            };
        }
        // boundary junction: the donor side by the mixture velocity, or by the pressure
        // difference when the fluid is at rest
        let (b, c, inflow_sign) = if j == 0 { (inlet, cell(0), 1.0) } else { (outlet, cell(n - 1), -1.0) };
        let vm = s.alpha[if j == 0 { 0 } else { n - 1 }] * s.v_g[j]
            + (1.0 - s.alpha[if j == 0 { 0 } else { n - 1 }]) * s.v_l[j];
        let p_cell = s.p[if j == 0 { 0 } else { n - 1 }];
        let inflow = if vm.abs() > 1e-9 {
            inflow_sign * vm > 0.0
        } else {
            inflow_sign * (if j == 0 { b.p - p_cell } else { p_cell - b.p }) > 0.0
        };
        if inflow && !matches!(b.kind, BoundaryKind::Closed) { bnd(b) } else { c }
    }

    /// Smallest gas volume fraction and smallest liquid mass share ([`liquid_share`]) of the two
    /// cells at junction `j`: the arguments of the phases' presence weights.
    fn junction_min_fractions(&self, s: &State, j: usize) -> (f64, f64) {
        let n = self.grid.n;
        // at a boundary junction the cell decides: the boundary's composition only describes
        // fluid that would enter
        let (l, r) = match (j == 0, j == n) {
            (true, _) => (0, 0),
            (_, true) => (n - 1, n - 1),
            _ => (j - 1, j),
        };
        (s.alpha[l].min(s.alpha[r]), liquid_share(s, l).min(liquid_share(s, r)))
    }

    fn junction_coefficients(
        &self,
        s: &State,
        j: usize,
        inlet: &BoundaryState,
        outlet: &BoundaryState,
        grav: f64,
    ) -> JunctionCoefficients {
        let g = &self.grid;
        let ph = &self.physics;
        let n = g.n;
        let js = self.junction_state(s, j, inlet, outlet);
        let (a_g, a_l) = (js.alpha, 1.0 - js.alpha);
        let ar_g = a_g * js.rho_g;
        let ar_l = a_l * js.rho_l;
        let (vg, vl) = (s.v_g[j], s.v_l[j]);
        // the closures see the junction through its donor cell, with the junction's velocities
        let donor = if j == 0 {
            0
        } else if j == n {
            n - 1
        } else if a_g * vg + a_l * vl >= 0.0 {
            j - 1
        } else {
            j
        };
        let mut local = self.local(s, donor);
        local.v_g = vg;
        local.v_l = vl;
        local.alpha = a_g;
        local.d_h = g.d_h_junction(j);
        let cp = &ph.cryo;
        let regime = cryo::flow_regime(&local, cp, s.wall_heat_flux[donor]);
        let rough = 0.5 * (g.relative_roughness[j.saturating_sub(1)] + g.relative_roughness[j.min(n - 1)]);
        let (f_g, f_l) = if ph.wall_friction { cryo::wall_friction(&local, cp, &regime, rough) } else { (0.0, 0.0) };
        let fric = |f: f64, a: f64| if a > 0.0 { f } else { 0.0 };
        let mut fric_g = fric(f_g, a_g);
        let mut fric_l = fric(f_l, a_l);
        // form loss (valve / entrance) at a boundary junction: K ρ |v| / (2 dx), the valve
        // closing the area scales K with 1/open²
        let bnd = if j == 0 {
            Some(inlet)
        } else if j == n {
            Some(outlet)
        } else {
            None
        };
        let dxj = g.dx_junction(j);
        if let Some(b) = bnd {
            let open = b.open_fraction.max(1e-6);
            let k = b.loss / (open * open) + if open < 1.0 { (1.0 / open - 1.0).powi(2) } else { 0.0 };
            fric_g += k * ar_g * vg.abs() / (2.0 * dxj);
            fric_l += k * ar_l * vl.abs() / (2.0 * dxj);
        }
        let rho_m = a_g * js.rho_g + a_l * js.rho_l;
        let drag_physical = if ph.interphase_drag { cryo::interfacial_drag(&local, cp, &regime) } else { 0.0 };
        // Newton linearisation of the drag force G(v_r) = F(v_r) v_r about the old relative
        // velocity: G(v_r^{n+1}) ≈ G' v_r^{n+1} + (F − G') v_r^n. The Picard form F(v_r^n) v_r^{n+1}
        // maps v_r^n to v_r^{n+1} with slope −(dlnF/dlnv_r) at equilibrium once the step is long
        // against the drag's relaxation time: the mist's Weber drops (d ∝ v_r⁻², F ∝ v_r³) then
        // oscillate from step to step with growing amplitude, and held the NBS runs to
        // millisecond steps wherever mist left the line. With the Newton form the slope is 0 and
        // the steady state (G = driving force) is unchanged. G' is a one-sided
        // difference in v_r (1 %), used only where the drag grows faster than linearly (G' > F:
        // a weaker growth is stable in the Picard form) and capped at 8 F.
        let (drag_newton, drag_explicit) = {
            let vr = vg - vl;
            if drag_physical > 0.0 && vr.abs() > 1e-3 {
                let mut shifted = local;
                shifted.v_g = vl + vr * (1.0 + NEWTON_DRAG_STEP);
                let f2 = cryo::interfacial_drag(&shifted, cp, &regime);
                let slope = drag_physical + (f2 - drag_physical) / NEWTON_DRAG_STEP;
                let k = if slope.is_finite() { slope.clamp(drag_physical, 8.0 * drag_physical) } else { drag_physical };
                (k, (k - drag_physical) * vr)
            } else {
                (drag_physical, 0.0)
            }
        };
        let mut drag = drag_newton;
        // A disappearing phase is tied to the continuous one (phase blending, paper eq.
        // "smoother"). At a junction a phase counts as disappearing when either neighbouring
        // cell (nearly) lacks it: its velocity there is otherwise undetermined by anything
        // physical, and through the convective term it would drag the neighbouring junctions.
        // (the junction's own fractions count too: fluid drawn from a liquid reservoir has no gas)
        let (side_g, side_l) = self.junction_min_fractions(s, j);
        let share_l = if ar_g + ar_l > 0.0 { ar_l / (ar_g + ar_l) } else { a_l };
        let pres = presence(side_g.min(side_l).min(a_g).min(share_l), ph.cryo.blend_min, ph.cryo.blend_max);
        drag += (1.0 - pres) * rho_m / BLEND_RELAXATION_S;
        let vm = if ph.virtual_mass { cryo::virtual_mass_coefficient(&local, cp) * a_g * a_l * rho_m } else { 0.0 };
        let (p_l, p_r) = (if j == 0 { inlet.p } else { s.p[j - 1] }, if j == n { outlet.p } else { s.p[j] });
        JunctionCoefficients {
            a_g,
            a_l,
            ar_g: ar_g.max(1e-9 * rho_m),
            ar_l: ar_l.max(1e-9 * rho_m),
            fric_g,
            fric_l,
            drag,
            drag_explicit,
            vm,
            dp_old: p_r - p_l,
            gx: -grav * g.sin_junction[j],
        }
    }

    /// The closures' view of cell `i` at the old time level.
    fn local(&self, s: &State, i: usize) -> cryo::Local {
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
    /// temperature eliminated implicitly), and the cell's new wetted-wall fraction.
    fn sources(&self, s: &State, i: usize, dt: f64) -> (Sources, f64) {
        let g = &self.grid;
        let ph = &self.physics;
        let cp = &ph.cryo;
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let a = s.alpha[i];
        let b = 1.0 - a;
        let v = g.volume[i];
        let pres_g = presence(a, ph.cryo.blend_min, ph.cryo.blend_max);
        let pres_l = presence(liquid_share(s, i), ph.cryo.blend_min, ph.cryo.blend_max);
        let gas_here = present(s.m_g[i], s.m_l[i]);
        let liq_here = present(s.m_l[i], s.m_g[i]);
        let tg = Lin::var(s.t_g[i], 2);
        let tl = Lin::var(s.t_l[i], 3);
        let sat = s.sat[i];
        let has_sat = sat.h_lg > 0.0;
        let mut local = self.local(s, i);
        if liq_here && has_sat && ph.wall_heat_transfer && ph.fixed_wall_htc.is_none() {
            local = local.with_boiling_basis(self.fluid);
        }
        let regime = cryo::flow_regime(&local, cp, s.wall_heat_flux[i]);
        // The wetted fraction relaxes to its regime value with the time constant tauw, but never
        // below the perimeter the liquid covers by geometry alone: a pool in the bottom of the
        // tube touches δ/π of the wall at once (film boiling under it is the boiling curve's
        // business). Decision: tauw is the time of the wetting *dynamics* (spreading into a film,
        // drying); without the floor, a large tauw keeps the wall of a cell that has filled with
        // liquid heating only the few per cent of vapour left in it, which is not physical and
        // drives the cell to runaway pressures.
        let w_eq = if liq_here { cryo::wetted_fraction(&local, &regime) } else { 0.0 };
        let w_geometric = if liq_here { cryo::stratified_half_angle(b) / std::f64::consts::PI } else { 0.0 };
        let wetted =
            (w_eq + (s.wetted[i] - w_eq) * (-dt / cp.wetting_time_constant.max(1e-9)).exp()).max(w_geometric.min(w_eq));
        // wall heat transfer coefficients per unit fluid volume
        let per_vol = g.perimeter[i] / g.area_cell[i];
        let (hw_g, hw_l, boiling) = if ph.wall_heat_transfer {
            match ph.fixed_wall_htc {
                Some(h) => (h * per_vol * a, h * per_vol * b, 0.0),
                None => {
                    let wh = cryo::wall_heat(&local, cp, ph.correlations, wetted, &regime);
                    (wh.h_wg * per_vol, wh.h_wl * per_vol, wh.boiling_fraction)
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
        let rec = if ph.fixed_wall_htc.is_none() { cryo::recovery_temperature_rise(&local) } else { 0.0 };
        let t_gw = tg.add(Lin::constant(rec));
        let den = c_w / dt + hw_g + hw_l + h_amb;
        let a0 =
            (-hw_g * (tw - s.t_g[i] - rec) - hw_l * (tw - s.t_l[i]) + h_amb * (ph.ambient_temperature_k - tw)) / den;
        let t_w_new = Lin { c0: tw + a0, c: [0.0, 0.0, hw_g / den, hw_l / den] };
        let q_wg = t_w_new.sub(t_gw).scale(hw_g);
        let q_wl = t_w_new.sub(tl).scale(hw_l);
        let q_amb = Lin::constant(h_amb * ph.ambient_temperature_k).sub(t_w_new.scale(h_amb));
        let q_wall = q_wg.add(q_wl);

        let mut s_g = q_wg;
        let mut s_l = q_wl;
        let mut gamma = Lin::default();
        let (mut pc_g, mut pc_l) = (Lin::default(), Lin::default());
        let blend = |pres: f64, m: f64, cp: f64| (1.0 - pres) * m.max(0.0) * cp / BLEND_RELAXATION_S;
        // Liquid above its saturation temperature flashes even where no vapour is left
        // (cryo::flashing_htc: bubbles nucleate): the vapour it makes starts the gas phase.
        let flashing = liq_here && has_sat && s.t_l[i] > sat.t_sat;
        if ph.phase_change && has_sat && liq_here && (gas_here || flashing) {
            // wall evaporation (paper: Γ_wg = q_wl/(H*_g − H*_l), scaled by Gwsc): the boiling
            // share of the wall heat to the liquid turns liquid at its own enthalpy into
            // saturated vapour; the liquid keeps q_wl − Γ_w h_g,sat, the vapour gains Γ_w h_g,sat
            let dh_w = (sat.h_g - lp.h).max(1e-3 * sat.h_lg);
            let mut g_w = q_wl.scale(cp.wall_mass_transfer_scale * boiling / dh_w);
            // A phase cannot give more mass than it has: where a step would evaporate (or
            // condense) more than half of what is left of a vanishing phase, the transfer is
            // scaled down so that it empties over a few steps instead of going negative (a
            // smaller step would do the same; this saves the hundreds of thousands of steps a
            // trace of condensing vapour in subcooled liquid otherwise costs).
            let mass_limit = |rate: f64, available: f64| -> f64 {
                let take = rate.abs() * dt;
                if take > 0.5 * available { 0.5 * available / take } else { 1.0 }
            };
            if g_w.c0 > 0.0 {
                g_w = g_w.scale(mass_limit(g_w.c0, s.m_l[i]));
            }
            s_l = s_l.sub(g_w.scale(sat.h_g));
            s_g = s_g.add(g_w.scale(sat.h_g));
            // interface: Γ_ig = −(q_ig + q_il)/(h*_g − h*_l), Gisc scaling the exchange
            let iph = if ph.interphase_heat_transfer {
                cryo::interphase_heat(&local, cp, &regime)
            } else {
                cryo::Interphase { h_ig: 0.0, h_il: 0.0 }
            };
            let scale = cp.interface_mass_transfer_scale;
            let ts = Lin { c0: sat.t_sat, c: [sat.dt_sat_dp, 0.0, 0.0, 0.0] };
            // Vapour below its saturation temperature is metastable and condenses on the liquid
            // within milliseconds: it is relaxed to T_sat with BLEND_RELAXATION_S, fully from
            // 1 K of subcooling on (RELAP5 does the same with a large gas-side coefficient).
            // Decision: the closures' interface areas (drops, films) are made for superheated
            // vapour; without this, vapour expanded in a pressure swing of a liquid-filled cell
            // cooled 15–20 K below saturation, towards the end of its property table.
            let subcooled_gas = smooth_step(sat.t_sat - s.t_g[i]) * s.m_g[i].max(0.0) * gp.cp / BLEND_RELAXATION_S;
            let mut h_ig = scale * iph.h_ig + blend(pres_g, s.m_g[i], gp.cp) + subcooled_gas;
            let mut h_il = scale * iph.h_il + blend(pres_l, s.m_l[i], lp.cp);
            let q_sum = h_ig * (sat.t_sat - s.t_g[i]) + h_il * (sat.t_sat - s.t_l[i]);
            let (hg_star, hl_star) = if q_sum <= 0.0 { (sat.h_g, lp.h) } else { (gp.h, sat.h_l) };
            let dh = (hg_star - hl_star).max(1e-3 * sat.h_lg);
            // the same mass limit on the interface transfer (both sides scaled: the interface
            // energy balance holds)
            let rate = -q_sum / dh;
            let f = if rate < 0.0 { mass_limit(rate, s.m_g[i]) } else { mass_limit(rate, s.m_l[i]) };
            h_ig *= f;
            h_il *= f;
            let q_ig = ts.sub(tg).scale(h_ig);
            let q_il = ts.sub(tl).scale(h_il);
            // (h*: RELAP5's switch — vapour forms at saturation from liquid at its own enthalpy,
            // condenses from vapour at its own enthalpy into saturated liquid)
            let g_ig = q_ig.add(q_il).scale(-1.0 / dh);
            s_g = s_g.add(q_ig).add(g_ig.scale(hg_star));
            s_l = s_l.add(q_il).sub(g_ig.scale(hl_star));
            gamma = g_ig.add(g_w);
            pc_g = q_ig.add(g_ig.scale(hg_star)).add(g_w.scale(sat.h_g));
            pc_l = q_il.sub(g_ig.scale(hl_star)).sub(g_w.scale(sat.h_g));
        } else {
            // no phase change: a plain exchange between the phases
            let h_exchange = if ph.interphase_heat_transfer { ph.interphase_htc_w_m3k * a * b } else { 0.0 };
            let h_blend = blend(pres_g, s.m_g[i], gp.cp) + blend(pres_l, s.m_l[i], lp.cp);
            let q = tl.sub(tg).scale(h_exchange + h_blend);
            s_g = s_g.add(q);
            s_l = s_l.sub(q);
        }
        (Sources { gamma, s_g, s_l, q_wall, q_amb, pc_g, pc_l }, wetted)
    }

    /// Total energy (h + v²/2 + g z) carried in minus out through the boundaries over the
    /// step, J, and the magnitude of its kinetic and potential parts, J.
    fn total_energy_flux(&self, next: &State, dt: f64, inlet: &BoundaryState, outlet: &BoundaryState) -> (f64, f64) {
        let g = &self.grid;
        let n = g.n;
        let z_in = 0.0;
        let z_out: f64 = (0..n).map(|i| g.dx[i] * g.sin_cell[i]).sum();
        let grav = if self.physics.gravity { GRAVITY } else { 0.0 };
        let mut total = 0.0;
        let mut mechanical = 0.0;
        for (j, b, z, sign) in [(0usize, inlet, z_in, 1.0), (n, outlet, z_out, -1.0)] {
            let area = g.area_junction[j] * b.open_fraction;
            for gas in [true, false] {
                let v = if gas { next.v_g[j] } else { next.v_l[j] };
                let inflow = sign * v > 0.0;
                let c = if j == 0 { 0 } else { n - 1 };
                let (m, h) = if inflow {
                    let (m, _, _) = boundary_conserved(b, gas);
                    (m, if gas { b.gas.h } else { b.liquid.h })
                } else {
                    // leaving: the cell's new internal energy (the scheme's donor) plus the flow
                    // work against the boundary pressure
                    let (m, e, rho) = if gas {
                        (next.m_g[c], next.e_g[c], next.gas[c].rho)
                    } else {
                        (next.m_l[c], next.e_l[c], next.liquid[c].rho)
                    };
                    (m, if m > 0.0 { e / m } else { 0.0 } + b.p / rho)
                };
                // fluid drawn from a reservoir brings its stagnation enthalpy (it was at rest)
                let ke = if inflow && b.kind == BoundaryKind::Reservoir { 0.0 } else { 0.5 * v * v };
                let mass = dt * v * area * m;
                total += sign * mass * (h + ke + grav * z);
                mechanical += (mass * (ke + grav * z)).abs();
            }
        }
        (total, mechanical)
    }
}

/// Heat that the forces of junction `j`'s momentum equations put into the fluid over a step,
/// per unit volume of the junction's control volume, W/m³: the kinetic energy they took from
/// the flow at the velocities `v1` (gas, liquid), the upstream junctions at `vt` (the velocities
/// of the momentum solve before the pressure correction, which the convective term used), and
/// the donor masses `mass` of the continuity equation's fluxes.
///
/// Decision: every loss of kinetic energy in the discrete momentum equations is heat, booked
/// where it happens, so that the internal-energy equations keep the paper's total energy
/// (internal plus kinetic). With the velocity implicit, a force f changes the kinetic energy by
/// f v¹ Δt less the time-step loss ½ ρ (v¹ − v⁰)². Booked here: wall friction and form losses
/// F (v¹)², the interphase drag's work at v¹ (its Newton part and the blending tie included),
/// and the donor-cell convection c (v_j − v_up) v_j less the kinetic energy ½ m_up |v| Δx⁻¹
/// (v_j² − v_up²) that the continuity equation's mass flux carries (the momentum equation's
/// α ρ is the junction mean, the mass flux the donor cell's): that is its numerical viscosity
/// ½ c (v_j − v_up)² plus the kinetic energy the two disagree about. Friction heat F v⁰ v¹ and
/// the drag's physical part alone, booked before, left 4.2 kJ (saturated 3.4 atm) to 24 kJ
/// (para-hydrogen) of the run's energy unaccounted; a numerical viscosity dissipates like a
/// physical one. Not booked: the time-step loss itself (0.03-0.2 kJ over the NBS runs, left
/// in the reported residual). With it booked, the separation problem kept a 2.5 % vapour pocket
/// under its liquid level, held there by the blending tie of the junctions on either side
/// (a disappearing phase is tied where either cell nearly lacks it).
fn booked_heat(m: &JunctionWork, j: usize, v1: [&[f64]; 2], vt: [&[f64]; 2], mass: [&[f64]; 2], dx_j: f64) -> f64 {
    let (g1, l1) = (v1[0][j], v1[1][j]);
    let r1 = g1 - l1;
    let mut heat = m.fric[0] * g1 * g1 + m.fric[1] * l1 * l1 + (m.drag * r1 - m.drag_explicit) * r1;
    for k in 0..2 {
        if let Some((c, up)) = m.conv[k] {
            let (v, v_up, vt_up) = (v1[k][j], v1[k][up], vt[k][up]);
            let cell = if up < j { j - 1 } else { j };
            let carried = mass[k][cell].max(0.0) * v.abs() / dx_j;
            heat += c * (v - vt_up) * v - 0.5 * carried * (v * v - v_up * v_up);
        }
    }
    heat
}

/// Conserved quantities per unit volume of the fluid entering through a boundary:
/// (mass, internal energy, phase fraction) of the gas or the liquid.
fn boundary_conserved(b: &BoundaryState, gas: bool) -> (f64, f64, f64) {
    if gas {
        (b.alpha * b.gas.rho, b.alpha * b.gas.rho * b.gas.u, b.alpha)
    } else {
        let a = 1.0 - b.alpha;
        (a * b.liquid.rho, a * b.liquid.rho * b.liquid.u, a)
    }
}

#[derive(Debug, Clone, Copy)]
struct Donor {
    m_g: f64,
    m_l: f64,
    e_g: f64,
    e_l: f64,
    a_g: f64,
    a_l: f64,
}

impl Donor {
    fn from_boundary(b: &BoundaryState) -> Self {
        let (m_g, e_g, a_g) = boundary_conserved(b, true);
        let (m_l, e_l, a_l) = boundary_conserved(b, false);
        Self { m_g, m_l, e_g, e_l, a_g, a_l }
    }
}

#[derive(Debug, Clone, Copy)]
struct JunctionState {
    alpha: f64,
    rho_g: f64,
    rho_l: f64,
}

/// A junction's momentum coefficients that do work on the flow (per unit volume), kept from
/// step 1 to book that work as heat in step 2.
#[derive(Debug, Clone, Copy, Default)]
struct JunctionWork {
    /// Wall friction and form-loss coefficients, N s/m⁴.
    fric: [f64; 2],
    /// Implicit drag coefficient (physical slope and blending tie), N s/m⁴.
    drag: f64,
    /// Explicit part of the Newton-linearised drag, N/m³.
    drag_explicit: f64,
    /// Gas and liquid donor-cell convection: the coefficient α ρ |v| / Δx (junction mean α ρ),
    /// kg/(m³ s), and the upstream junction; `None` where the term has a Bernoulli form or there
    /// is no upstream junction.
    conv: [Option<(f64, usize)>; 2],
}

#[derive(Debug, Clone, Copy)]
struct JunctionCoefficients {
    a_g: f64,
    a_l: f64,
    ar_g: f64,
    ar_l: f64,
    fric_g: f64,
    fric_l: f64,
    /// Implicit interphase drag coefficient (the Newton slope of the physical drag plus the
    /// phase-blending tie), N s/m⁴.
    drag: f64,
    /// Explicit part of the Newton-linearised drag on the gas, (G' − F) v_r^n, N/m³ (the liquid
    /// gets its negative).
    drag_explicit: f64,
    vm: f64,
    dp_old: f64,
    gx: f64,
}

fn resize(w: &mut Work, n: usize) {
    let nj = n + 1;
    let m = nj.max(n);
    w.mech.resize(nj, JunctionWork::default());
    for v in [&mut w.vt_g, &mut w.vt_l, &mut w.w_g, &mut w.w_l, &mut w.junction_heat] {
        v.resize(nj, 0.0);
    }
    for v in [&mut w.a, &mut w.b, &mut w.c, &mut w.d, &mut w.s] {
        v.resize(n, 0.0);
    }
    w.lower.resize(m, Matrix2::zeros());
    w.diag.resize(m, Matrix2::zeros());
    w.upper.resize(m, Matrix2::zeros());
    w.rhs2.resize(m, Vector2::zeros());
    w.scratch2.resize(m, Matrix2::zeros());
    w.minv.resize(n, Matrix4::zeros());
    w.r4.resize(n, Vector4::zeros());
    w.cl.resize(n, Vector4::zeros());
    w.cr.resize(n, Vector4::zeros());
    w.sources.resize(n, Sources::default());
    w.wetted.resize(n, 0.0);
    for v in [
        &mut w.heat_g,
        &mut w.heat_l,
        &mut w.dp,
        &mut w.mass_g,
        &mut w.mass_l,
        &mut w.dvol_g,
        &mut w.dvol_l,
        &mut w.gamma_used,
        &mut w.sg_used,
        &mut w.sl_used,
    ] {
        v.resize(n, 0.0);
    }
    w.reset.resize(n, false);
    w.alpha_mom.resize(nj, None);
    w.work_fix.resize(n, 0.0);
    w.x.resize(n, Vector4::zeros());
}

/// Saturation properties at `p`, or all zeros where there are none (above the critical pressure
/// or below the triple point): `h_lg = 0` then switches phase change off for the cell.
pub fn saturation_or_none(fluid: &FluidTable, p: f64) -> Saturation {
    fluid.saturation(p).unwrap_or(Saturation { pressure_pa: p, ..Saturation::default() })
}

/// Mass fraction below which a phase counts as absent in a cell: its energy equation is replaced
/// and it takes no heat. (Donor-cell fluxes spread vanishing amounts, down to denormal numbers,
/// which must not reach the closures.)
pub const PRESENT_MASS_FRACTION: f64 = 1e-12;

/// Is a phase of mass `m` present next to the other phase's mass `other` (per unit volume)?
#[inline]
/// The liquid's share of the mass in cell `i`, m_l/(m_g + m_l).
///
/// Decision: the liquid's presence weight (phase blending, `blend_xmin`/`blend_xmax`) is taken
/// on its mass share, the gas's on its volume fraction. Blending is numerics for a phase too
/// small to matter: liquid is that when it carries a negligible share of the mass, and a mist
/// behind a quench front at a volume fraction of 10⁻³ carries a fifth of it (ρ_l/ρ_g ≈ 200 for
/// nitrogen at 3 bar). Weighed by its volume fraction, that mist had its velocity tied to the
/// vapour's and its temperature relaxed to saturation, and the station-4 chilldowns moved by
/// 3–4 % between `blend_xmax` = 10⁻⁴ and 10⁻² (VALIDATION.md). Vapour in a liquid-filled cell
/// has a negligible mass share at any void fraction, so for the gas the volume fraction stays
/// the measure: below 1 % of the volume a vapour trace is bubbles that follow the liquid.
fn liquid_share(s: &State, i: usize) -> f64 {
    let (m_g, m_l) = (s.m_g[i].max(0.0), s.m_l[i].max(0.0));
    if m_g + m_l > 0.0 { m_l / (m_g + m_l) } else { 1.0 - s.alpha[i] }
}

fn present(m: f64, other: f64) -> bool {
    m > PRESENT_MASS_FRACTION * (m + other)
}
