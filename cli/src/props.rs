//! `cryofit props FLUID --p PA --t K [--json]`.

use anyhow::Result;
use clap::Args;
use serde::Serialize;

use crate::fluid_source;

/// Arguments of `cryofit props`.
#[derive(Debug, Args)]
pub struct PropsArgs {
    /// Fluid: nitrogen, hydrogen (normal), parahydrogen, oxygen or methane (aliases N2, H2, p-H2, O2, CH4).
    fluid: String,
    /// Pressure, Pa.
    #[arg(long = "p", value_name = "PA", allow_negative_numbers = true)]
    pressure_pa: f64,
    /// Temperature, K.
    #[arg(long = "t", value_name = "K", allow_negative_numbers = true)]
    temperature_k: f64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// The JSON document `cryofit props --json` prints (key names are a public contract).
#[derive(Debug, Serialize)]
struct PropsJson<'a> {
    fluid: &'a str,
    phase: &'a str,
    pressure_pa: f64,
    temperature_k: f64,
    density_kg_m3: f64,
    specific_enthalpy_j_kg: f64,
    specific_internal_energy_j_kg: f64,
    cp_j_kg_k: f64,
    viscosity_pa_s: f64,
    conductivity_w_m_k: f64,
    t_sat_k: Option<f64>,
}

/// Prints the stable state of a fluid at the given pressure and temperature.
pub fn run(args: &PropsArgs) -> Result<()> {
    let table = fluid_source::load(&args.fluid)?;
    let (p, t) = (args.pressure_pa, args.temperature_k);
    let s = table.stable_state(p, t)?;
    let out = PropsJson {
        fluid: table.name(),
        phase: s.label,
        pressure_pa: p,
        temperature_k: t,
        density_kg_m3: s.props.rho,
        specific_enthalpy_j_kg: s.props.h,
        specific_internal_energy_j_kg: s.props.u,
        cp_j_kg_k: s.props.cp,
        viscosity_pa_s: s.props.mu,
        conductivity_w_m_k: s.props.k,
        t_sat_k: s.t_sat,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let c = table.constants();
    println!("{} ({}) at p = {p} Pa, T = {t} K: {}", c.description, c.eos_reference, out.phase);
    let rows: [(&str, String, &str); 8] = [
        ("density", format!("{:.6}", out.density_kg_m3), "kg/m³"),
        ("specific enthalpy", format!("{:.3}", out.specific_enthalpy_j_kg), "J/kg"),
        ("specific internal energy", format!("{:.3}", out.specific_internal_energy_j_kg), "J/kg"),
        ("isobaric heat capacity", format!("{:.4}", out.cp_j_kg_k), "J/(kg K)"),
        ("viscosity", format!("{:.6e}", out.viscosity_pa_s), "Pa s"),
        ("thermal conductivity", format!("{:.6}", out.conductivity_w_m_k), "W/(m K)"),
        (
            "saturation temperature",
            match out.t_sat_k {
                Some(ts) => format!("{ts:.4}"),
                None if p >= c.p_critical_pa => "none (above the critical pressure)".into(),
                None if p > c.p_triple_pa => format!(
                    "none (within 0.5 % of the critical pressure, {:.0} Pa, where the table gives no saturation)",
                    c.p_critical_pa
                ),
                None => "none (below the triple-point pressure)".into(),
            },
            if out.t_sat_k.is_some() { "K" } else { "" },
        ),
        ("table", format!("CoolProp {}", c.coolprop_version), ""),
    ];
    for (name, value, unit) in rows {
        println!("  {name:<26}{value} {unit}");
    }
    Ok(())
}
