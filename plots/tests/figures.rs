//! Every kind of figure drawn from synthetic data, as SVG and PNG.

use cryofit_plots::*;

fn stages() -> Vec<String> {
    vec!["stage 1: sensitivity".into(), "stage 2: cmaes".into()]
}

fn history() -> Plot {
    let evaluations = (0..60)
        .map(|i| Evaluation {
            index: i,
            stage: usize::from(i >= 9),
            cost: (i % 13 != 5).then(|| 5000.0 / (1.0 + i as f64) + 40.0 + (i * 37 % 11) as f64 * 30.0),
        })
        .collect();
    Plot::CostHistory(CostHistory { title: "Cost <history>".into(), stages: stages(), evaluations })
}

fn traces() -> Plot {
    let mk = |name: &str, unit: &str, log: bool| Trace {
        name: name.into(),
        unit: unit.into(),
        log,
        points: (0..60).map(|i| (i, usize::from(i >= 9), 1.0 + (i as f64 * 0.7).sin() * 0.5)).collect(),
        best: Some(1.2),
    };
    Plot::Traces(Traces {
        title: "Parameter traces".into(),
        stages: stages(),
        traces: vec![mk("Gwsc", "", true), mk("hg0sc", "", false), mk("tauw", "s", false)],
    })
}

fn samples() -> Samples {
    let draws: Vec<Vec<f64>> = (0..400)
        .map(|i| {
            let a = ((i * 7919) % 1000) as f64 / 1000.0;
            let b = ((i * 104_729) % 1000) as f64 / 1000.0;
            vec![1.0 + a * 0.2, 2.0 + 0.5 * a + b * 0.1, 0.3 + b * 0.05]
        })
        .collect();
    Samples {
        title: "Posterior".into(),
        labels: vec!["Gwsc (dimensionless)".into(), "hg0sc (dimensionless)".into(), "tauw (s)".into()],
        draws,
        best: Some(vec![1.1, 2.3, 0.32]),
    }
}

fn all() -> Vec<Plot> {
    let fit = FitPanels {
        title: "sub42: wall temperature".into(),
        value_label: "wall temperature (K)".into(),
        value_scale: 1.0,
        band_label: "5–95 % posterior predictive".into(),
        panels: ["TS1", "TS2", "TS3"]
            .iter()
            .enumerate()
            .map(|(k, s)| StationPanel {
                station: (*s).into(),
                x_m: Some(6.1 + 18.0 * k as f64),
                data: (0..50)
                    .map(|i| (i as f64 * 4.0, 290.0 - 200.0 / (1.0 + (-(i as f64) * 0.2 + 5.0).exp())))
                    .collect(),
                model: (0..200).map(|i| (i as f64, 290.0 - 205.0 / (1.0 + (-(i as f64) * 0.05 + 5.0).exp()))).collect(),
                band: Some((0..200).map(|i| (i as f64, 280.0 - i as f64 * 0.5, 295.0 - i as f64 * 0.5)).collect()),
            })
            .collect(),
    };
    let boiling = BoilingCurves {
        title: "Boiling curve".into(),
        panels: [1.0, 3.0, 7.0]
            .iter()
            .map(|&atm| BoilingPanel {
                pressure_pa: atm * 101_325.0,
                t_sat_k: 77.0 + atm * 3.0,
                series: [0.0, 1e4, 1e5]
                    .iter()
                    .map(|&re| BoilingSeries {
                        reynolds: re,
                        points: (1..100)
                            .map(|i| (80.0 + i as f64 * 2.0, 1e3 * (1.0 + re / 1e4) * (i as f64).sqrt()))
                            .collect(),
                    })
                    .collect(),
            })
            .collect(),
    };
    let sens = Sensitivity {
        title: "Sensitivity".into(),
        score_label: "normalised effect on the cost".into(),
        panels: vec![RankingPanel {
            label: "stage 1: sensitivity".into(),
            bars: vec![
                RankedBar { name: "Gwsc".into(), score: Some(1.0), kept: true },
                RankedBar { name: "hg0sc".into(), score: Some(0.4), kept: true },
                RankedBar { name: "tauw".into(), score: None, kept: false },
            ],
        }],
    };
    vec![
        history(),
        traces(),
        Plot::Sensitivity(sens),
        Plot::Marginals(samples()),
        Plot::Corner(samples()),
        Plot::Fit(fit),
        Plot::Boiling(boiling),
    ]
}

#[test]
fn every_figure_draws_as_svg_and_png_with_its_labels() {
    let dump = std::env::var_os("CRYOFIT_PLOTS_DUMP");
    for (k, p) in all().iter().enumerate() {
        let svg = p.svg().unwrap_or_else(|e| panic!("{e}"));
        assert!(svg.starts_with("<svg"), "{}", &svg[..100.min(svg.len())]);
        // titles are escaped text of the document
        let escaped = escape_html(p.title()).replace("&#39;", "'");
        assert!(svg.contains(&escaped) || svg.contains(p.title()), "title of figure {k} missing");
        let png = p.png().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let (w, h) = p.size();
        assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), w);
        assert_eq!(u32::from_be_bytes(png[20..24].try_into().unwrap()), h);
        if let Some(dir) = &dump {
            std::fs::write(std::path::Path::new(dir).join(format!("{k}.png")), &png).unwrap();
            std::fs::write(std::path::Path::new(dir).join(format!("{k}.svg")), &svg).unwrap();
        }
    }
}

#[test]
fn axis_labels_carry_units_and_legends_name_series() {
    let all = all();
    let svg = |k: usize| all[k].svg().unwrap();
    assert!(svg(0).contains("evaluation") && svg(0).contains("stage 2: cmaes — best so far"));
    assert!(svg(1).contains("tauw (s)") && svg(1).contains("Gwsc (dimensionless)"));
    assert!(svg(2).contains("kept free") && svg(2).contains("tauw  n/a, fixed after the screen"));
    let fit = svg(5);
    assert!(
        fit.contains("station TS2 (x = 24.1 m)") && fit.contains("wall temperature (K)") && fit.contains("time (s)")
    );
    assert!(fit.contains("measured") && fit.contains("5–95 % posterior predictive"));
    let boiling = svg(6);
    assert!(
        boiling.contains("wall heat flux (W/m²)") && boiling.contains("p = 3 atm") && boiling.contains("Re_l = 1e4")
    );
}

#[test]
fn empty_and_degenerate_inputs_still_draw() {
    let empty = Plot::CostHistory(CostHistory { title: "none".into(), stages: vec![], evaluations: vec![] });
    assert!(empty.svg().is_ok() && empty.png().is_ok());
    let flat = Plot::Marginals(Samples {
        title: "flat".into(),
        labels: vec!["a".into()],
        draws: vec![vec![1.0]; 10],
        best: None,
    });
    assert!(flat.svg().is_ok() && flat.png().is_ok());
    let nan = Plot::CostHistory(CostHistory {
        title: "nan".into(),
        stages: vec![],
        evaluations: vec![Evaluation { index: 0, stage: 0, cost: Some(f64::NAN) }],
    });
    assert!(nan.svg().is_ok());
}

/// The `<rect x=.. y=.. width=.. height=..>` elements of an SVG, as numbers.
fn rects(svg: &str) -> Vec<[f64; 4]> {
    let attr = |tag: &str, name: &str| -> Option<f64> {
        let at = tag.find(&format!(" {name}=\""))? + name.len() + 3;
        tag[at..].split('"').next()?.parse().ok()
    };
    svg.split("<rect")
        .skip(1)
        .filter_map(|t| Some([attr(t, "x")?, attr(t, "y")?, attr(t, "width")?, attr(t, "height")?]))
        .collect()
}

#[test]
fn a_legend_too_long_for_its_panel_shrinks_and_keeps_its_swatches_inside() {
    let Plot::Fit(mut fit) = all().remove(5) else { panic!("figure 5 is the fit") };
    fit.band_label = "5–95 % band of a measurement with a label far longer than a quarter-width panel holds: \
                      the runs, the clock error and the misfit"
        .into();
    fit.panels.push(fit.panels[0].clone());
    let svg = Plot::Fit(fit).svg().unwrap();
    let all = rects(&svg);
    // the legend's box: the bordered rectangle drawn twice (background, border) at one place
    let boxes: Vec<&[f64; 4]> = all.iter().filter(|r| all.iter().filter(|s| s == r).count() == 2).collect();
    let b = boxes.first().expect("a legend box");
    // the band's swatch: 22 px wide and 12 high, inside the box
    let swatch = all.iter().find(|r| r[3] == 12.0).expect("the band's swatch");
    assert_eq!(swatch[2], 22.0, "the swatch keeps its width: {swatch:?}");
    assert!(swatch[0] > b[0] && swatch[0] + swatch[2] < b[0] + b[2], "swatch {swatch:?} inside the box {b:?}");
}
