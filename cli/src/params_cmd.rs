//! `cryofit params [--json]`: the parameter registry.

use anyhow::Result;
use clap::Args;
use cryofit_solver::params::{ParamSpec, REGISTRY};
use serde::Serialize;

use crate::output::fmt_num;

/// Arguments of `cryofit params`.
#[derive(Debug, Args)]
pub struct ParamsArgs {
    /// Print a JSON list of objects instead of a table.
    #[arg(long)]
    json: bool,
}

/// One registry entry as `cryofit params --json` prints it (key names are a public contract).
#[derive(Debug, Serialize)]
struct ParamJson<'a> {
    name: &'a str,
    group: &'a str,
    default: f64,
    lower: f64,
    upper: f64,
    unit: &'a str,
    description: &'a str,
}

impl<'a> From<&'a ParamSpec> for ParamJson<'a> {
    fn from(p: &'a ParamSpec) -> Self {
        Self {
            name: p.name,
            group: p.group,
            default: p.default,
            lower: p.lower,
            upper: p.upper,
            unit: p.unit,
            description: p.description,
        }
    }
}

/// Prints every registry parameter.
pub fn run(args: &ParamsArgs) -> Result<()> {
    if args.json {
        let list: Vec<ParamJson> = REGISTRY.iter().map(ParamJson::from).collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    let header = ["NAME", "GROUP", "DEFAULT", "LOWER", "UPPER", "UNIT", "DESCRIPTION"].map(String::from);
    let rows: Vec<[String; 7]> = REGISTRY
        .iter()
        .map(|p| {
            [
                p.name.to_string(),
                p.group.to_string(),
                fmt_num(p.default),
                fmt_num(p.lower),
                fmt_num(p.upper),
                p.unit.to_string(),
                p.description.to_string(),
            ]
        })
        .collect();
    let mut widths = [0usize; 7];
    for row in std::iter::once(&header).chain(&rows) {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    for row in std::iter::once(&header).chain(&rows) {
        let mut line = String::new();
        for (k, cell) in row.iter().enumerate() {
            if k + 1 == row.len() {
                line.push_str(cell);
            } else {
                let pad = widths[k] - cell.chars().count();
                line.push_str(cell);
                line.push_str(&" ".repeat(pad + 2));
            }
        }
        println!("{}", line.trim_end());
    }
    Ok(())
}
