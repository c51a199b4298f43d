//! Property-evaluation throughput: all properties and derivatives of one phase at one state.

use criterion::{Criterion, Throughput, black_box, criterion_group, criterion_main};
use cryofit_solver::fluids::{self, Phase};

/// Deterministic pseudo-random states inside the table's coverage of `phase`.
fn states(table: &fluids::FluidTable, phase: Phase, n: usize) -> Vec<(f64, f64)> {
    let c = table.constants();
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = (c.p_min_pa.ln() + next() * (c.p_max_pa / c.p_min_pa).ln()).exp();
        let Some((lo, hi)) = table.phase_temperature_range(phase, p) else { continue };
        out.push((p, lo + next() * (hi - lo)));
    }
    out
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("fluid_props");
    for name in ["nitrogen", "hydrogen"] {
        let table = fluids::embedded(name).expect("embedded table");
        for phase in Phase::ALL {
            let st = states(table, phase, 4096);
            group.throughput(Throughput::Elements(st.len() as u64));
            group.bench_function(format!("{name}/{phase}"), |b| {
                b.iter(|| {
                    let mut acc = 0.0;
                    for &(p, t) in &st {
                        let pr = table.phase_props(phase, black_box(p), black_box(t)).expect("in range");
                        acc += pr.rho
                            + pr.drho_dp
                            + pr.drho_dt
                            + pr.u
                            + pr.du_dp
                            + pr.du_dt
                            + pr.h
                            + pr.dh_dp
                            + pr.dh_dt
                            + pr.cp
                            + pr.mu
                            + pr.k;
                    }
                    black_box(acc)
                })
            });
        }
    }
    let table = fluids::embedded("nitrogen").expect("embedded table");
    group.throughput(Throughput::Elements(1));
    group.bench_function("nitrogen/saturation", |b| b.iter(|| table.saturation(black_box(3.1e5)).expect("in range")));
    group.bench_function("nitrogen/temperature_from_energy", |b| {
        b.iter(|| {
            table
                .temperature_from_energy(Phase::Liquid, black_box(3.1e5), black_box(-1.2e5), black_box(78.0))
                .expect("in range")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
