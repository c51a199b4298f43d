#!/usr/bin/env python3
"""Generate cryofit's fluid property tables and CoolProp check points.

Usage (from the repository root):

    tools/setup.sh --tables            # installs the pinned CoolProp (tools/requirements.txt)
    python3 tools/fluid_tables.py      # all five fluids, writes data/fluids/ (about 3 minutes)
    python3 tools/fluid_tables.py nitrogen oxygen  # only these

For every fluid the script writes

* ``data/fluids/<fluid>.cft``  -- the binary property table read by ``cryofit_solver::fluids``;
* ``data/fluids/<fluid>_check.csv`` and ``<fluid>_saturation_check.csv`` -- CoolProp check points
  (stable and metastable states; saturation states) that the solver's tests compare the table
  against.

The format is described in ``data/fluids/README.md``.  Each phase table is a tensor-product cubic
Hermite interpolant on a piecewise-uniform (pressure, temperature) grid: every node stores the
value and the derivatives d/dp, d/dT and d2/dpdT of density, specific internal energy, isobaric
heat capacity, viscosity and thermal conductivity of *that phase*, evaluated from the Helmholtz
equation of state with the phase imposed.  A phase is therefore one smooth function of (p, T)
that continues through the saturation line into its metastable region (superheated liquid,
subcooled vapour), which a two-fluid model visits at every quench front.  Rows stop 20 K (plus a
margin of two grid intervals) past saturation, at the triple-point temperature, or where the
isotherm reaches the spinodal (no mechanically stable density left, or dp/drho|T below 2 % of
its saturation value), whichever comes first. Rows that end at the spinodal keep clear of it by
1 % of the critical temperature, and the header records the spinodal temperature, located by
bisection. Above the critical pressure both phase tables hold the one supercritical fluid; where
a row's density branch cannot follow it across the pseudo-critical line (a temperature node just
below Tc), the row continues from the equilibrium density.

Pressures run from 1 kPa to 30 MPa (the pressure surges of a chilldown line reach several MPa,
above the critical pressure of hydrogen and nitrogen, and its liquid hammer can pass 10 MPa),
temperatures from the triple point to 500 K (a surge compresses the warm gas ahead of it, and the
gas heats as it is compressed). ``hydrogen`` is normal hydrogen, ``parahydrogen`` para-hydrogen
(see data/fluids/README.md for which to use when).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import struct
import sys
from pathlib import Path

import numpy as np
import CoolProp
import CoolProp.CoolProp as CP

FORMAT_MAGIC = b"CRYOFLT1"
FORMAT_VERSION = 1

# (table name, CoolProp name, human name)
FLUIDS = {
    "nitrogen": ("Nitrogen", "nitrogen (N2)"),
    "hydrogen": ("Hydrogen", "normal hydrogen (n-H2)"),
    "parahydrogen": ("ParaHydrogen", "para-hydrogen (p-H2)"),
    "oxygen": ("Oxygen", "oxygen (O2)"),
    "methane": ("Methane", "methane (CH4)"),
}

P_MIN = 1.0e3  # 0.01 bar
P_MAX = 3.0e7  # 300 bar: the liquid hammer of a chilldown line can pass 10 MPa (see pressure_segments)
# The finely noded range: the critical regions and the surges a chilldown line usually reaches.
P_DENSE = 1.0e7
# Node spacing above P_DENSE, up to P_MAX (supercritical, far from every fluid's critical point).
P_HIGH_STEP = 1.0e6
# The top of the temperature axis. Up to T_BASE_MAX the nodes are those of the earlier 350 K
# tables; above it a segment of T_HIGH_STEP spacing carries the gas that a pressure surge
# compresses: the line's gas starts near 290 K, and compressed adiabatically by a factor of 3
# (a first-contact surge at the envelope's 11 atm drive) it reaches about 400 K.
T_BASE_MAX = 350.0
T_MAX = 500.0
T_HIGH_STEP = 10.0
METASTABLE_K = 20.0  # required reach past the saturation line
MARGIN_INTERVALS = 2  # extra grid intervals computed past that reach
# A metastable row ends where dp/drho|T has fallen below this fraction of its value on the
# saturation line: beyond it c_p and the compressibility diverge towards the spinodal.
SPINODAL_FRACTION = 0.02
# ... or where du/dT|p has risen to this multiple of its value at the row's first metastable node.
SPINODAL_DUDT_RISE = 10.0
# Metastable rows that end at the spinodal drop their nodes closer to it than this fraction of Tc.
SPINODAL_MARGIN_TC = 0.01
PROPS = ("rho", "u", "cp", "mu", "k")


def axis_segments(breaks, steps):
    """Piecewise-uniform axis: segment k runs breaks[k]..breaks[k+1] with about steps[k] spacing."""
    segs = []
    for a, b, h in zip(breaks[:-1], breaks[1:], steps):
        n = max(1, int(math.ceil((b - a) / h - 1e-9)))
        segs.append((float(a), float(b), n))
    return segs


def axis_nodes(segs):
    nodes = [segs[0][0]]
    for a, b, n in segs:
        for i in range(1, n + 1):
            nodes.append(a + (b - a) * i / n)
    return np.array(nodes)


# Finer nodes near the critical point, as (temperature factor, pressure factor): the temperature
# spacing from 0.97 Tc to 1.06 Tc and the pressure spacing from 0.8 pc to 1.1 pc are divided by
# them. The base grid's nodes stay where they were, so states away from the critical point
# interpolate exactly as before. Oxygen and methane: at the base spacing the solver's loader
# cannot keep their interpolants thermodynamically stable along the pseudo-critical line
# (solver/tests/fluid_stability.rs finds them). The hydrogens: with the base 20 kPa (1.5 % of
# their critical pressure) and 0.15 K, the liquid rows near the critical point end at the
# spinodal before the cells between two rows reach the saturation temperature of the upper row,
# so that saturated liquid at 93 % of the critical pressure (the NBS 11 atm condition) lay
# outside the liquid table.
NEAR_CRITICAL_REFINE = {"oxygen": (4, 1), "methane": (4, 1), "hydrogen": (4, 4), "parahydrogen": (4, 4)}


def fluid_axes(cp_name, refine=(1, 1)):
    """Grids per fluid: fine temperature spacing up to 1.3 Tc, coarser above."""
    a = CP.AbstractState("HEOS", cp_name)
    ttr, tc, pc = a.Ttriple(), a.T_critical(), a.p_critical()
    t_fine_end = 1.3 * tc
    # roughly 200 fine intervals below 1.3 Tc, then ~4 % of Tc up to 2.2 Tc, then ~8 K
    fine = (t_fine_end - ttr) / 200.0
    t_refine, p_refine = refine
    if t_refine > 1:
        # break points on nodes of the base grid, so that no base node moves
        k_lo = math.floor((0.97 * tc - ttr) / fine)
        k_hi = math.ceil((1.06 * tc - ttr) / fine)
        t_breaks = [ttr, ttr + k_lo * fine, ttr + k_hi * fine, t_fine_end]
        t_steps = [fine, fine / t_refine, fine]
    else:
        t_breaks = [ttr, t_fine_end]
        t_steps = [fine]
    if 2.2 * tc < T_BASE_MAX:
        t_breaks += [2.2 * tc, T_BASE_MAX]
        t_steps += [0.04 * tc, 8.0]
    else:
        t_breaks += [T_BASE_MAX]
        t_steps += [0.04 * tc]
    t_breaks += [T_MAX]
    t_steps += [T_HIGH_STEP]
    return pressure_segments(pc, p_refine), axis_segments(t_breaks, t_steps)


# Supercritical pressure segments above 1.1 pc: (upper end / pc, spacing / pc). The spacing grows
# with the distance from the critical point, a piecewise-uniform stand-in for a geometric grid.
SUPERCRITICAL_STEPS = ((1.6, 0.025), (2.5, 0.05), (4.0, 0.1), (math.inf, 0.2))


def pressure_segments(pc, refine=1):
    """Pressure grid: log-like segments at low pressure, finest around the critical pressure.

    1-5 kPa every 0.5 kPa, 5-100 kPa every 5 kPa, 0.1-1 MPa every 25 kPa, then every 50 kPa up to
    0.8 pc, every 20 kPa from 0.8 to 1.1 pc, and coarser with distance above it (within each
    segment the spacing is as close to the nominal one as a whole number of intervals allows).
    """
    p_breaks = [P_MIN, 5.0e3, 1.0e5, 1.0e6]
    p_steps = [5.0e2, 5.0e3, 2.5e4]
    if 0.8 * pc > p_breaks[-1]:
        p_breaks.append(0.8 * pc)
        p_steps.append(5.0e4)
    p_breaks.append(1.1 * pc)
    p_steps.append(2.0e4 / refine)
    for hi, step in SUPERCRITICAL_STEPS:
        p_breaks.append(min(hi * pc, P_DENSE))
        p_steps.append(step * pc)
        if p_breaks[-1] >= P_DENSE:
            break
    # Above 10 MPa every 1 MPa: the first-contact liquid hammer of subcooled nitrogen at 11 atm
    # drive passed 10 MPa (the Joukowsky surge ρ c Δv of a 15 m/s column), and ended the run at
    # the table's edge.
    p_breaks.append(P_MAX)
    p_steps.append(P_HIGH_STEP)
    assert p_breaks[-1] == P_MAX and all(b > a for a, b in zip(p_breaks, p_breaks[1:]))
    return axis_segments(p_breaks, p_steps)


class Eos:
    """Single-phase Helmholtz-EOS evaluations with the phase imposed."""

    def __init__(self, cp_name, phase):
        self.a = CP.AbstractState("HEOS", cp_name)
        self.a.specify_phase(CP.iphase_liquid if phase == "liquid" else CP.iphase_gas)
        self.phase = phase

    def density(self, p, t, rho0):
        """Newton on p(rho, T) = p from rho0, staying on the mechanically stable branch.

        A step that lands where dp/drho|T <= 0 (past the spinodal) is halved until it does not,
        so that the iteration never leaves the branch it started on.
        """
        a = self.a

        def eval_at(rho):
            a.update(CP.DmassT_INPUTS, rho, t)
            return a.p() - p, a.first_partial_deriv(CP.iP, CP.iDmass, CP.iT)

        rho = rho0
        try:
            f, dpdr = eval_at(rho)
        except ValueError:
            return None
        if not (dpdr > 0.0):
            return None
        best = (abs(f), rho, dpdr)
        for _ in range(100):
            step = f / dpdr
            lim = 0.2 * rho
            if abs(step) > lim:
                step = math.copysign(lim, step)
            for _ in range(40):
                trial = rho - step
                ok = trial > 0.0
                if ok:
                    try:
                        f_t, d_t = eval_at(trial)
                        ok = d_t > 0.0 and math.isfinite(f_t)
                    except ValueError:
                        ok = False
                if ok:
                    break
                step *= 0.5
            else:
                return None
            rho, f, dpdr = trial, f_t, d_t
            if abs(step) < 1e-13 * rho and abs(f) < 1e-9 * max(p, 1.0):
                a.update(CP.DmassT_INPUTS, rho, t)
                return rho
            best = min(best, (abs(f), rho, dpdr))
        # Round-off in p(rho, T) can keep both tests from passing together: near the critical
        # point (dp/drho|T small, so the step stays above 1e-13 rho) and in a stiff liquid at low
        # pressure (the residual stays above 1e-9 p). Accept the best iterate when its residual
        # is below 1e-9 p or amounts to a relative density error below 1e-12.
        f_best, rho, dpdr = best
        if f_best <= max(1e-9 * max(p, 1.0), 1e-12 * rho * dpdr):
            a.update(CP.DmassT_INPUTS, rho, t)
            return rho
        return None

    def values(self, p, t, rho0):
        rho = self.density(p, t, rho0)
        if rho is None:
            return None
        a = self.a
        a.update(CP.DmassT_INPUTS, rho, t)
        return rho, {
            "rho": rho,
            "u": a.umass(),
            "cp": a.cpmass(),
            "mu": a.viscosity(),
            "k": a.conductivity(),
            "dpdrho": a.first_partial_deriv(CP.iP, CP.iDmass, CP.iT),
        }

    def first_derivs(self):
        """Analytic d/dp|T and d/dT|p of rho, u and c_p at the current state."""
        a = self.a
        iD, iU, iH, iP, iT = CP.iDmass, CP.iUmass, CP.iHmass, CP.iP, CP.iT
        return {
            "rho": (a.first_partial_deriv(iD, iP, iT), a.first_partial_deriv(iD, iT, iP)),
            "u": (a.first_partial_deriv(iU, iP, iT), a.first_partial_deriv(iU, iT, iP)),
            "cp": (a.second_partial_deriv(iH, iT, iP, iP, iT), a.second_partial_deriv(iH, iT, iP, iT, iP)),
        }

    def node(self, p, t, rho0):
        """Value, d/dp, d/dT and d2/dpdT of every tabulated property at (p, t)."""
        base = self.values(p, t, rho0)
        if base is None:
            return None
        rho, v = base
        d0 = self.first_derivs()
        dp = max(1e-5 * p, 1e-2)
        dt = 1e-4 * t
        out = {}
        # shifted states for finite differences (same branch: start from rho)
        shifted = {}
        for key, (pp, tt) in {
            "p+": (p + dp, t), "p-": (p - dp, t), "t+": (p, t + dt), "t-": (p, t - dt),
            "++": (p + dp, t + dt), "+-": (p + dp, t - dt), "-+": (p - dp, t + dt), "--": (p - dp, t - dt),
        }.items():
            r = self.values(pp, tt, rho)
            if r is None:
                return None
            shifted[key] = (r[1], self.first_derivs())
        for name in PROPS:
            f = v[name]
            if name in d0:
                fp, ft = d0[name]
                # cross derivative: d/dp of the analytic d/dT
                fpt = (shifted["p+"][1][name][1] - shifted["p-"][1][name][1]) / (2 * dp)
            else:
                fp = (shifted["p+"][0][name] - shifted["p-"][0][name]) / (2 * dp)
                ft = (shifted["t+"][0][name] - shifted["t-"][0][name]) / (2 * dt)
                fpt = (shifted["++"][0][name] - shifted["+-"][0][name] - shifted["-+"][0][name]
                       + shifted["--"][0][name]) / (4 * dp * dt)
            out[name] = (f, fp, ft, fpt)
        return rho, v["dpdrho"], out


class Saturation:
    def __init__(self, cp_name):
        self.a = CP.AbstractState("HEOS", cp_name)
        self.ttr = self.a.Ttriple()
        self.ptr = self.a.p_triple()
        self.tc = self.a.T_critical()
        self.pc = self.a.p_critical()

    def t_sat(self, p):
        self.a.update(CP.PQ_INPUTS, p, 0.0)
        return self.a.T()

    def at_t(self, t, q):
        self.a.update(CP.QT_INPUTS, q, t)
        return self.a

    def dpdrho_sat(self, t, q):
        a = self.at_t(t, q)
        rho = a.rhomass()
        e = CP.AbstractState("HEOS", a.name())
        e.specify_phase(CP.iphase_liquid if q == 0 else CP.iphase_gas)
        e.update(CP.DmassT_INPUTS, rho, t)
        return rho, e.first_partial_deriv(CP.iP, CP.iDmass, CP.iT)


def build_phase(cp_name, phase, p_nodes, t_nodes, sat, t_step_at):
    """March every pressure row along T from the stable side; return rows of (j_lo, node data)."""
    eos = Eos(cp_name, phase)
    flash = CP.AbstractState("HEOS", cp_name)
    rows = []
    nt = len(t_nodes)
    for i, p in enumerate(p_nodes):
        subcritical = p < sat.pc
        ps = max(p, sat.ptr)
        tsat = sat.t_sat(ps) if ps < sat.pc else None
        # A cell between two rows answers only where both rows do, so each row reaches 20 K past
        # the saturation temperature of its neighbour: the next pressure for the liquid (whose
        # reach grows with pressure), the previous one for the gas.
        p_nb = p_nodes[min(i + 1, len(p_nodes) - 1)] if phase == "liquid" else p_nodes[max(i - 1, 0)]
        ps_nb = max(p_nb, sat.ptr)
        tsat_nb = sat.t_sat(ps_nb) if ps_nb < sat.pc else None
        nodes = {}
        if phase == "liquid":
            order = range(nt)
            if subcritical:
                reach_from = tsat_nb if tsat_nb is not None else tsat
                limit = reach_from + METASTABLE_K + MARGIN_INTERVALS * t_step_at(reach_from + METASTABLE_K)
            else:
                limit = math.inf
            # stable compressed liquid at the triple temperature
            rho_guess = sat.at_t(sat.ttr, 0.0).rhomass()
        else:
            order = range(nt - 1, -1, -1)
            if subcritical:
                reach_from = min(tsat_nb, tsat) if tsat_nb is not None else tsat
                limit = reach_from - METASTABLE_K - MARGIN_INTERVALS * t_step_at(max(reach_from - METASTABLE_K, sat.ttr))
            else:
                limit = -math.inf
            rho_guess = None
        dpdrho_ref = None
        spinodal = None
        last_good = None  # (T, rho, dp/drho) of the last node on the row
        last_dpdrho = None
        dudt_ref = None  # du/dT|p at the row's first metastable node
        for j in order:
            t = t_nodes[j]
            if phase == "liquid" and t > limit + 1e-9:
                break
            # a subcritical liquid row never crosses the critical temperature: past the liquid
            # spinodal the liquid branch ends, and the states above Tc belong to the gas table
            if phase == "liquid" and subcritical and t >= sat.tc:
                break
            if phase == "gas" and t < limit - 1e-9:
                break
            if phase == "gas" and rho_guess is None:
                a = CP.AbstractState("HEOS", cp_name)
                a.update(CP.PT_INPUTS, p, t)
                rho_guess = a.rhomass()
            metastable = subcritical and ((phase == "liquid" and t > tsat) or (phase == "gas" and t < tsat))
            if metastable and dpdrho_ref is None:
                _, dpdrho_ref = sat.dpdrho_sat(tsat, 0.0 if phase == "liquid" else 1.0)
            r = eos.node(p, t, rho_guess)
            if r is None and not subcritical:
                # Above the critical pressure there is one fluid, whose density changes steeply
                # but continuously across the pseudo-critical line. Where that line falls
                # between two temperature nodes on either side of Tc, the branch the row was
                # following (gas-like or liquid-like) does not reach p at the next node:
                # continue from the equilibrium density.
                try:
                    flash.update(CP.PT_INPUTS, p, t)
                    r = eos.node(p, t, flash.rhomass())
                except ValueError:
                    r = None
            ended = r is None
            if not ended:
                rho, dpdrho, data = r
                if metastable:
                    # Deeper into the metastable region dp/drho|T falls monotonically to zero
                    # at the spinodal. A rise means the iteration has slipped onto one of the
                    # spurious loops a multiparameter EOS has inside the two-phase dome.
                    # Near the spinodal du/dT|p diverges too, and on a row that the triple
                    # point ends before dp/drho|T has fallen far (methane gas at 125 kPa, 24 K
                    # below saturation: du/dT|p 36 times its value near saturation) the
                    # interpolant between that row and the next cannot follow it.
                    if dudt_ref is None:
                        dudt_ref = data["u"][2]
                    ended = (dpdrho < SPINODAL_FRACTION * dpdrho_ref
                             or (last_dpdrho is not None and dpdrho > last_dpdrho)
                             or abs(rho - rho_guess) > 0.2 * rho_guess
                             or data["u"][2] > SPINODAL_DUDT_RISE * dudt_ref)
            if ended:
                if metastable and last_good is not None:
                    spinodal = locate_spinodal(eos, p, last_good, t)
                    if spinodal is not None:
                        # keep clear of the spinodal, where c_p and the compressibility diverge
                        # and no interpolant can follow them
                        # but never the nodes the stable states of the neighbouring cell need
                        # (near the critical point the spinodal closes in on saturation)
                        t_need = tsat_nb if tsat_nb is not None else tsat
                        h = t_step_at(t_need)
                        for jj in list(nodes):
                            tj = t_nodes[jj]
                            needed = tj <= t_need + h if phase == "liquid" else tj >= t_need - h
                            if not needed and abs(tj - spinodal) < SPINODAL_MARGIN_TC * sat.tc:
                                del nodes[jj]
                break
            nodes[j] = data
            rho_guess = rho
            last_good = (t, rho, dpdrho)
            last_dpdrho = dpdrho
        if not nodes:
            rows.append((0, [], None))
            continue
        js = sorted(nodes)
        assert js == list(range(js[0], js[-1] + 1))
        rows.append((js[0], [nodes[j] for j in js], spinodal))
    return rows


def locate_spinodal(eos, p, last_good, t_next):
    """Temperature where the phase's density branch ends at pressure p (dp/drho|T -> 0).

    Steps on from the last tabulated node while a density continues the branch (converged,
    dp/drho|T still positive and still falling, no jump), then bisects.
    """
    t_ok, rho_ok, d_ok = last_good

    def follow(t, rho_prev, d_prev):
        r = eos.values(p, t, rho_prev)
        if r is None:
            return None
        rho, v = r
        if v["dpdrho"] > d_prev or abs(rho - rho_prev) > 0.2 * rho_prev:
            return None
        return rho, v["dpdrho"]

    step = 0.25 * (t_next - t_ok)
    t_bad = None
    for _ in range(800):
        r = follow(t_ok + step, rho_ok, d_ok)
        if r is None:
            t_bad = t_ok + step
            break
        t_ok, (rho_ok, d_ok) = t_ok + step, r
    if t_bad is None:
        return None
    for _ in range(40):
        mid = 0.5 * (t_ok + t_bad)
        r = follow(mid, rho_ok, d_ok)
        if r is None:
            t_bad = mid
        else:
            t_ok, (rho_ok, d_ok) = mid, r
    return t_ok


def sat_tables(sat, p_lo, p_hi_frac=0.995):
    """Saturation properties vs pressure and saturation pressure vs temperature."""
    a = sat.a
    p_hi = p_hi_frac * sat.pc
    # nodes uniform in ln p, densified towards the critical point in sqrt distance
    s = np.linspace(0.0, 1.0, 500)
    p_nodes = np.exp(math.log(p_lo) + (math.log(p_hi) - math.log(p_lo)) * (1 - (1 - s) ** 1.5))
    names = ("t_sat", "rho_l", "rho_g", "h_l", "h_g", "sigma")
    sp = []
    for p in p_nodes:
        row = []
        a.update(CP.PQ_INPUTS, p, 0.0)
        t = a.T()
        dTdp = a.first_saturation_deriv(CP.iT, CP.iP)
        rho_l = a.rhomass()
        drl = a.first_saturation_deriv(CP.iDmass, CP.iP)
        h_l = a.hmass()
        dhl = a.first_saturation_deriv(CP.iHmass, CP.iP)
        sigma = a.surface_tension()
        a.update(CP.PQ_INPUTS, p, 1.0)
        rho_g = a.rhomass()
        drg = a.first_saturation_deriv(CP.iDmass, CP.iP)
        h_g = a.hmass()
        dhg = a.first_saturation_deriv(CP.iHmass, CP.iP)
        # d sigma/dp by central difference along the saturation line
        dp = 1e-5 * p
        a.update(CP.PQ_INPUTS, p + dp, 0.0)
        s_p = a.surface_tension()
        a.update(CP.PQ_INPUTS, p - dp, 0.0)
        s_m = a.surface_tension()
        dsig = (s_p - s_m) / (2 * dp)
        sp.append([t, dTdp, rho_l, drl, rho_g, drg, h_l, dhl, h_g, dhg, sigma, dsig])
    # p_sat(T)
    a.update(CP.PQ_INPUTS, p_hi, 0.0)
    t_hi = a.T()
    t_nodes = np.linspace(sat.ttr, t_hi, 500)
    st = []
    for t in t_nodes:
        a.update(CP.QT_INPUTS, 0.0, t)
        st.append([a.p(), a.first_saturation_deriv(CP.iP, CP.iT)])
    return names, p_nodes, np.array(sp), t_nodes, np.array(st)


def melting_nodes(cp_name, p_nodes, ttr):
    a = CP.AbstractState("HEOS", cp_name)
    out = []
    for p in p_nodes:
        try:
            tm = a.melting_line(CP.iT, CP.iP, p)
        except ValueError:
            tm = ttr
        out.append(max(ttr, tm) if math.isfinite(tm) else ttr)
    return np.array(out)


def write_table(name, cp_name, human, out_dir):
    sat = Saturation(cp_name)
    p_segs, t_segs = fluid_axes(cp_name, NEAR_CRITICAL_REFINE.get(name, (1, 1)))
    p_nodes, t_nodes = axis_nodes(p_segs), axis_nodes(t_segs)

    def t_step_at(t):
        for a, b, n in t_segs:
            if t <= b:
                return (b - a) / n
        return (t_segs[-1][1] - t_segs[-1][0]) / t_segs[-1][2]

    phases = {}
    for phase in ("liquid", "gas"):
        print(f"  {name}: {phase} table ({len(p_nodes)} x {len(t_nodes)} grid)", file=sys.stderr)
        phases[phase] = build_phase(cp_name, phase, p_nodes, t_nodes, sat, t_step_at)
    sat_names, sp_nodes, sp, st_nodes, st = sat_tables(sat, sat.ptr)
    melt = melting_nodes(cp_name, p_nodes, sat.ttr)

    a = sat.a
    header = {
        "format": FORMAT_VERSION,
        "fluid": name,
        "description": human,
        "coolprop_name": cp_name,
        "coolprop_version": CoolProp.__version__,
        "eos_reference": CP.get_fluid_param_string(cp_name, "BibTeX-EOS"),
        "molar_mass_kg_mol": a.molar_mass(),
        "gas_constant_j_kg_k": a.gas_constant() / a.molar_mass(),
        "t_triple_k": sat.ttr,
        "p_triple_pa": sat.ptr,
        "t_critical_k": sat.tc,
        "p_critical_pa": sat.pc,
        "p_min_pa": P_MIN,
        "p_max_pa": P_MAX,
        "t_max_k": T_MAX,
        "metastable_k": METASTABLE_K,
        "p_axis": [[a_, b_, n_] for a_, b_, n_ in p_segs],
        "t_axis": [[a_, b_, n_] for a_, b_, n_ in t_segs],
        "properties": list(PROPS),
        "phases": {},
        "saturation": {
            "p_nodes": len(sp_nodes),
            "columns": ["t_sat", "dt_sat_dp", "rho_l", "drho_l_dp", "rho_g", "drho_g_dp", "h_l", "dh_l_dp",
                        "h_g", "dh_g_dp", "sigma", "dsigma_dp"],
            "t_nodes": len(st_nodes),
            "t_columns": ["p_sat", "dp_sat_dt"],
        },
        "melting_nodes": len(melt),
    }
    blobs = []
    for phase, rows in phases.items():
        j_lo = [r[0] for r in rows]
        count = [len(r[1]) for r in rows]
        spin = [r[2] for r in rows]
        header["phases"][phase] = {"row_first": j_lo, "row_count": count, "row_spinodal_k": spin}
        data = []
        for _, nodes, _ in rows:
            for node in nodes:
                for prop in PROPS:
                    data.extend(node[prop])
        blobs.append(("f32", np.array(data, dtype="<f4")))
    blobs.append(("f64", np.asarray(sp_nodes, dtype="<f8")))
    blobs.append(("f64", np.asarray(sp, dtype="<f8").ravel()))
    blobs.append(("f64", np.asarray(st_nodes, dtype="<f8")))
    blobs.append(("f64", np.asarray(st, dtype="<f8").ravel()))
    blobs.append(("f64", np.asarray(melt, dtype="<f8")))
    header["blobs"] = [[kind, int(arr.size)] for kind, arr in blobs]
    hjson = json.dumps(header, separators=(",", ":")).encode()
    body = b"".join(arr.tobytes() for _, arr in blobs)
    path = out_dir / f"{name}.cft"
    with open(path, "wb") as f:
        f.write(FORMAT_MAGIC)
        f.write(struct.pack("<I", len(hjson)))
        f.write(hjson)
        f.write(body)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    print(f"  wrote {path} ({path.stat().st_size / 1e6:.2f} MB, sha256 {digest[:16]})", file=sys.stderr)
    return coverage_fn(phases, p_nodes, t_nodes)


def coverage_fn(phases, p_nodes, t_nodes):
    """(phase, p) -> (T_lo, T_hi) the table answers, mirroring PhaseTable::cell_range in Rust."""

    def cover(phase, p):
        rows = phases[phase]
        i = int(np.searchsorted(p_nodes, p, side="right")) - 1
        i = min(max(i, 0), len(p_nodes) - 2)
        (fa, na), (fb, nb) = (rows[i][0], len(rows[i][1])), (rows[i + 1][0], len(rows[i + 1][1]))
        lo, hi = max(fa, fb), min(fa + na, fb + nb) - 1
        if na == 0 or nb == 0 or hi < lo + 1:
            return None
        return t_nodes[lo], t_nodes[hi]

    return cover


def check_points(name, cp_name, out_dir, cover, seed=20261122):
    """CoolProp reference states the Rust tests compare the table against."""
    rng = np.random.default_rng(seed)
    a = CP.AbstractState("HEOS", cp_name)
    ttr, ptr, tc, pc = a.Ttriple(), a.p_triple(), a.T_critical(), a.p_critical()
    rows = []
    # stable single-phase states, log-uniform in pressure, uniform in temperature
    n = 0
    while n < 400:
        p = math.exp(rng.uniform(math.log(P_MIN), math.log(P_MAX)))
        t = rng.uniform(ttr, T_MAX)
        try:
            tm = a.melting_line(CP.iT, CP.iP, p)
        except ValueError:
            tm = ttr
        if t < max(ttr, tm):
            continue
        if ptr <= p < pc:
            a.update(CP.PQ_INPUTS, p, 0.0)
            ts = a.T()
            if abs(t - ts) < 0.05:
                continue
            phase = "liquid" if t < ts else "gas"
        elif p < ptr:
            phase = "gas"
        else:
            phase = "supercritical"
        a.unspecify_phase()
        try:
            a.update(CP.PT_INPUTS, p, t)
        except ValueError:
            continue
        rows.append(("stable", phase, p, t, a.rhomass(), a.hmass(), a.umass(), a.cpmass(), a.viscosity(),
                     a.conductivity()))
        n += 1
    # stable states near the critical point, where the tables are least accurate
    n = 0
    while n < 60:
        p = rng.uniform(max(0.75 * pc, P_MIN), min(1.25 * pc, P_MAX))
        t = rng.uniform(0.95 * tc, 1.05 * tc)
        if p < pc:
            a.unspecify_phase()
            a.update(CP.PQ_INPUTS, p, 0.0)
            ts = a.T()
            if abs(t - ts) < 0.05:
                continue
            phase = "liquid" if t < ts else "gas"
        else:
            phase = "supercritical"
        a.unspecify_phase()
        try:
            a.update(CP.PT_INPUTS, p, t)
        except ValueError:
            continue
        rows.append(("stable", phase, p, t, a.rhomass(), a.hmass(), a.umass(), a.cpmass(), a.viscosity(),
                     a.conductivity()))
        n += 1
    # metastable states within 20 K of saturation (or the spinodal), phase imposed
    for phase in ("liquid", "gas"):
        e = Eos(cp_name, phase)
        m = 0
        tries = 0
        while m < 60 and tries < 2000:
            tries += 1
            p = math.exp(rng.uniform(math.log(max(ptr, P_MIN) * 1.01), math.log(min(pc, P_MAX) * 0.9)))
            a.unspecify_phase()
            a.update(CP.PQ_INPUTS, p, 0.0 if phase == "liquid" else 1.0)
            ts, rs = a.T(), a.rhomass()
            dt = rng.uniform(0.1, METASTABLE_K)
            t = ts + dt if phase == "liquid" else ts - dt
            span = cover(phase, p)
            if t < ttr or span is None or not (span[0] < t < span[1]):
                continue
            r = e.values(p, t, rs)
            if r is None:
                continue
            _, v = r
            h = v["u"] + p / v["rho"]
            rows.append(("metastable", phase, p, t, v["rho"], h, v["u"], v["cp"], v["mu"], v["k"]))
            m += 1
    with open(out_dir / f"{name}_check.csv", "w") as f:
        f.write(f"# CoolProp {CoolProp.__version__}, fluid {cp_name} "
                f"({CP.get_fluid_param_string(cp_name, 'BibTeX-EOS')} EOS); SI units; written by tools/fluid_tables.py\n")
        f.write("kind,phase,p_pa,t_k,rho_kg_m3,h_j_kg,u_j_kg,cp_j_kgk,mu_pa_s,k_w_mk\n")
        for r in rows:
            f.write(",".join([r[0], r[1]] + [repr(float(x)) for x in r[2:]]) + "\n")
    # saturation check points
    with open(out_dir / f"{name}_saturation_check.csv", "w") as f:
        f.write(f"# CoolProp {CoolProp.__version__}, fluid {cp_name}; saturation states; SI units; "
                f"written by tools/fluid_tables.py\n")
        f.write("p_pa,t_sat_k,rho_l_kg_m3,rho_v_kg_m3,h_l_j_kg,h_v_j_kg,sigma_n_m\n")
        for p in np.exp(rng.uniform(math.log(ptr * 1.001), math.log(0.99 * min(pc, P_MAX)), 60)):
            a.update(CP.PQ_INPUTS, p, 0.0)
            t, rl, hl, sg = a.T(), a.rhomass(), a.hmass(), a.surface_tension()
            a.update(CP.PQ_INPUTS, p, 1.0)
            f.write(",".join(repr(float(x)) for x in (p, t, rl, a.rhomass(), hl, a.hmass(), sg)) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("fluids", nargs="*", default=list(FLUIDS), help="fluids to generate (default: all)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "data" / "fluids"))
    args = ap.parse_args()
    if CoolProp.__version__ != open(Path(__file__).with_name("requirements.txt")).read().split("CoolProp==")[1].split()[0]:
        sys.exit(f"CoolProp {CoolProp.__version__} installed; tools/requirements.txt pins another version. "
                 "Run tools/setup.sh --tables first.")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.fluids:
        if name not in FLUIDS:
            sys.exit(f"unknown fluid '{name}'; known: {', '.join(FLUIDS)}")
        cp_name, human = FLUIDS[name]
        print(f"{name}:", file=sys.stderr)
        cover = write_table(name, cp_name, human, out)
        check_points(name, cp_name, out, cover)


if __name__ == "__main__":
    main()
