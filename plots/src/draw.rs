//! Drawing: every figure becomes a title and a grid of panels, each panel an x–y chart with
//! layers (lines, markers, bands, bars, text), drawn on the SVG or the bitmap backend.

use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::{BoilingCurves, CostHistory, FitPanels, Plot, Samples, Sensitivity, Traces};

type Res = Result<(), String>;

/// DejaVu Sans, registered once as plotters' `sans-serif`.
static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

fn fonts() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "the built-in DejaVu Sans font cannot be read".to_string())
    })
    .clone()
}

const FAMILY: &str = "sans-serif";
const TITLE_PX: f64 = 26.0;
/// Width of a legend entry's swatch column, px (the swatches are 22 px wide).
const LEGEND_SWATCH_PX: u32 = 30;
/// A legend's margin around its entries, px.
const LEGEND_MARGIN_PX: u32 = 8;

/// Colour-blind-friendly categorical colours (Okabe–Ito, with black last).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 94, 40),
    RGBColor(0, 0, 0),
];

fn colour(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

const DATA_COLOUR: RGBColor = RGBColor(0, 0, 0);
const MODEL_COLOUR: RGBColor = RGBColor(213, 94, 0);
const BAND_COLOUR: RGBColor = RGBColor(0, 114, 178);

// ---------------------------------------------------------------------------------------------
// panels

#[derive(Debug, Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    /// An axis over the finite values (positive ones on a log axis), padded by 5 %.
    fn over(values: impl IntoIterator<Item = f64>, log: bool) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            if v.is_finite() && (!log || v > 0.0) {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if !lo.is_finite() {
            return if log { Self { lo: 0.1, hi: 10.0, log } } else { Self { lo: 0.0, hi: 1.0, log } };
        }
        if log {
            // whole decades, so that at least two labelled ticks show
            let (a, b) = (lo.log10().floor(), hi.log10().ceil());
            let b = if b <= a { a + 1.0 } else { b };
            // (a hair outside, so that rounding in the log coordinate keeps the end labels)
            return Self { lo: 10f64.powf(a) * (1.0 - 1e-9), hi: 10f64.powf(b) * (1.0 + 1e-9), log };
        }
        let span = hi - lo;
        let pad = if span > 0.0 { span * 0.05 } else { lo.abs().max(1.0) * 0.05 };
        Self { lo: lo - pad, hi: hi + pad, log }
    }

    fn fixed(lo: f64, hi: f64) -> Self {
        Self { lo, hi, log: false }
    }
}

#[derive(Debug, Clone)]
enum Layer {
    Line { pts: Vec<(f64, f64)>, colour: RGBColor, width: u32, label: Option<String> },
    Dots { pts: Vec<(f64, f64)>, colour: RGBColor, alpha: f64, size: u32, label: Option<String> },
    Band { pts: Vec<(f64, f64, f64)>, colour: RGBColor, label: Option<String> },
    Rects { rects: Vec<Rect>, colour: RGBColor, label: Option<String> },
    Text { at: (f64, f64), text: String },
}

#[derive(Debug, Clone)]
struct Panel {
    caption: String,
    x_label: String,
    y_label: String,
    x: Axis,
    y: Axis,
    layers: Vec<Layer>,
    legend: Option<SeriesLabelPosition>,
    /// Draw tick labels on the value axis.
    y_ticks: bool,
    /// Font size of tick labels, px (axis descriptions are 2 px larger).
    font: f64,
}

impl Panel {
    fn new(
        caption: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
        x: Axis,
        y: Axis,
    ) -> Self {
        Self {
            caption: caption.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            x,
            y,
            layers: Vec::new(),
            legend: None,
            y_ticks: true,
            font: 15.0,
        }
    }
}

/// A figure: title, grid, panels in row order (fewer panels than cells leave cells empty).
struct Layout {
    title: String,
    rows: usize,
    cols: usize,
    panels: Vec<Option<Panel>>,
}

/// Four significant digits, scientific outside 10⁻² … 10⁴, without trailing zeros.
pub(crate) fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    if !(1e-2..1e4).contains(&a) {
        let s = format!("{v:.2e}");
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        let m = m.trim_end_matches('0').trim_end_matches('.');
        return format!("{m}e{e}");
    }
    let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

fn render_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Res {
    let (x, y) = (p.x.lo..p.x.hi, p.y.lo..p.y.hi);
    match (p.x.log, p.y.log) {
        (false, false) => render_with(area, p, x, y),
        (false, true) => render_with(area, p, x, y.log_scale()),
        (true, false) => render_with(area, p, x.log_scale(), y),
        (true, true) => render_with(area, p, x.log_scale(), y.log_scale()),
    }
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

fn render_with<DB, X, Y>(area: &DrawingArea<DB, Shift>, p: &Panel, x: X, y: Y) -> Res
where
    DB: DrawingBackend,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let f = p.font;
    let mut builder = ChartBuilder::on(area);
    builder.margin(8).margin_right(18).x_label_area_size((f * 3.2) as u32).y_label_area_size(if p.y_ticks {
        (f * 5.6) as u32
    } else {
        (f * 2.0) as u32
    });
    if !p.caption.is_empty() {
        builder.caption(&p.caption, (FAMILY, f + 4.0));
    }
    let mut chart = builder.build_cartesian_2d(x, y).map_err(err)?;
    let fmt = |v: &f64| tick(*v);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .x_labels(6)
        .label_style((FAMILY, f))
        .axis_desc_style((FAMILY, f + 2.0))
        .light_line_style(RGBColor(0, 0, 0).mix(0.04))
        .bold_line_style(RGBColor(0, 0, 0).mix(0.12));
    if p.y_ticks {
        mesh.y_labels(6);
    } else {
        mesh.y_labels(0);
    }
    mesh.draw().map_err(err)?;
    let legend_line =
        |c: RGBColor, w: u32| move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 22, y)], c.stroke_width(w));
    // the longest legend label, if any, to fit the legend's font to the panel
    let mut label_chars: Option<usize> = None;
    let mut note_label = |l: &str| label_chars = Some(label_chars.unwrap_or(0).max(l.chars().count()));
    for layer in &p.layers {
        match layer {
            Layer::Band { pts, colour, label } => {
                if pts.len() < 2 {
                    continue;
                }
                let mut poly: Vec<(f64, f64)> = pts.iter().map(|&(t, lo, _)| (t, lo)).collect();
                poly.extend(pts.iter().rev().map(|&(t, _, hi)| (t, hi)));
                let c = *colour;
                let a = chart.draw_series(std::iter::once(Polygon::new(poly, c.mix(0.25).filled()))).map_err(err)?;
                if let Some(l) = label {
                    note_label(l);
                    a.label(l.as_str())
                        .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 22, y + 6)], c.mix(0.25).filled()));
                }
            }
            Layer::Rects { rects, colour, label } => {
                let c = *colour;
                let a = chart
                    .draw_series(
                        rects
                            .iter()
                            .map(|&(x0, y0, x1, y1)| Rectangle::new([(x0, y0), (x1, y1)], c.mix(0.75).filled())),
                    )
                    .map_err(err)?;
                if let Some(l) = label {
                    note_label(l);
                    a.label(l.as_str())
                        .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 22, y + 6)], c.mix(0.75).filled()));
                }
            }
            Layer::Line { pts, colour, width, label } => {
                let (c, w) = (*colour, *width);
                let a = chart.draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(w))).map_err(err)?;
                if let Some(l) = label {
                    note_label(l);
                    a.label(l.as_str()).legend(legend_line(c, w));
                }
            }
            Layer::Dots { pts, colour, alpha, size, label } => {
                let (c, a, s) = (*colour, *alpha, *size);
                let drawn =
                    chart.draw_series(pts.iter().map(|&pt| Circle::new(pt, s, c.mix(a).filled()))).map_err(err)?;
                if let Some(l) = label {
                    note_label(l);
                    drawn.label(l.as_str()).legend(move |(x, y)| Circle::new((x + 11, y), s.max(3), c.filled()));
                }
            }
            Layer::Text { at, text } => {
                let style = TextStyle::from((FAMILY, f).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
                chart.draw_series(std::iter::once(Text::new(text.clone(), *at, style))).map_err(err)?;
            }
        }
    }
    if let (Some(chars), Some(pos)) = (label_chars, p.legend.clone()) {
        // a legend wider than the plot is pinned to its left edge with its swatches outside it:
        // its font shrinks to fit instead (DejaVu Sans averages under 0.6 em per character), as
        // the figure's title does
        let width = f64::from(chart.plotting_area().dim_in_pixel().0);
        // the swatches, the legend's margins and plotters' 5 px offset from the plot's edge
        let room = width - f64::from(LEGEND_SWATCH_PX + 2 * LEGEND_MARGIN_PX + 2 * 5);
        let legend_px = f.min(room / (0.6 * chars.max(1) as f64)).max(7.0);
        chart
            .configure_series_labels()
            .position(pos)
            .legend_area_size(LEGEND_SWATCH_PX)
            .label_font((FAMILY, legend_px))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(0, 0, 0).mix(0.4))
            .margin(LEGEND_MARGIN_PX)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

fn render<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, layout: &Layout) -> Res {
    root.fill(&WHITE).map_err(err)?;
    // a long title shrinks to fit the figure's width (DejaVu Sans averages about 0.55 em per
    // character) rather than running off both edges
    let width = f64::from(root.dim_in_pixel().0);
    let chars = layout.title.chars().count().max(1) as f64;
    let title_px = TITLE_PX.min(0.95 * width / (0.55 * chars)).max(12.0);
    let body = root.titled(&layout.title, (FAMILY, title_px)).map_err(err)?;
    let cells = body.split_evenly((layout.rows.max(1), layout.cols.max(1)));
    for (cell, panel) in cells.iter().zip(&layout.panels) {
        if let Some(p) = panel {
            render_panel(cell, p)?;
        }
    }
    root.present().map_err(err)?;
    Ok(())
}

fn grid(n: usize, max_cols: usize) -> (usize, usize) {
    let cols = n.clamp(1, max_cols);
    (n.div_ceil(cols).max(1), cols)
}

// ---------------------------------------------------------------------------------------------
// figures → layouts

pub(crate) fn size(plot: &Plot) -> (u32, u32) {
    let l = layout(plot);
    let (rows, cols) = (l.rows as u32, l.cols as u32);
    match plot {
        Plot::CostHistory(_) => (1100, 640),
        Plot::Traces(_) | Plot::Marginals(_) => (if cols == 1 { 900 } else { 1200 }, 70 + rows * 320),
        Plot::Sensitivity(s) => {
            let bars: u32 = s.panels.iter().map(|p| p.bars.len().max(1) as u32).max().unwrap_or(1);
            (1000, 70 + rows * (130 + 34 * bars))
        }
        Plot::Corner(_) => {
            let side = (cols * 280 + 60).max(600);
            (side, side + 10)
        }
        Plot::Fit(_) => (if cols == 1 { 900 } else { 1300 }, 70 + rows * 380),
        Plot::Boiling(_) => (cols * 560, 80 + rows * 560),
    }
}

fn layout(plot: &Plot) -> Layout {
    match plot {
        Plot::CostHistory(c) => cost_history(c),
        Plot::Traces(t) => traces(t),
        Plot::Sensitivity(s) => sensitivity(s),
        Plot::Marginals(s) => marginals(s),
        Plot::Corner(s) => corner(s),
        Plot::Fit(f) => fit(f),
        Plot::Boiling(b) => boiling(b),
    }
}

fn stage_label(stages: &[String], k: usize) -> String {
    stages.get(k).cloned().unwrap_or_else(|| format!("stage {}", k + 1))
}

fn cost_history(c: &CostHistory) -> Layout {
    let costs: Vec<f64> = c.evaluations.iter().filter_map(|e| e.cost).collect();
    let positive = costs.iter().all(|&v| v > 0.0);
    let (lo, hi) = costs.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    let log = positive && !costs.is_empty() && hi / lo > 30.0;
    let x = Axis::over(c.evaluations.iter().map(|e| e.index as f64 + 1.0), false);
    let y = Axis::over(costs.iter().copied(), log);
    let mut p = Panel::new("", "evaluation", "cost S (weighted sum of squares, dimensionless)", x, y);
    let n_stages = c.evaluations.iter().map(|e| e.stage + 1).max().unwrap_or(0);
    // every evaluation, faint, by stage
    for k in 0..n_stages {
        let pts: Vec<(f64, f64)> = c
            .evaluations
            .iter()
            .filter(|e| e.stage == k)
            .filter_map(|e| e.cost.map(|v| (e.index as f64 + 1.0, v)))
            .collect();
        let failed = c.evaluations.iter().filter(|e| e.stage == k && e.cost.is_none()).count();
        let mut label = format!("{} — evaluations", stage_label(&c.stages, k));
        if failed > 0 {
            label.push_str(&format!(" ({failed} failed)"));
        }
        p.layers.push(Layer::Dots { pts, colour: colour(k), alpha: 0.35, size: 3, label: Some(label) });
    }
    // best so far, a step line coloured by the stage that held it
    let mut best = f64::INFINITY;
    let mut segments: Vec<(usize, Vec<(f64, f64)>)> = Vec::new();
    for e in &c.evaluations {
        let x = e.index as f64 + 1.0;
        if segments.last().is_none_or(|(k, _)| *k != e.stage) {
            let start = segments.last().and_then(|(_, s)| s.last().copied());
            segments.push((e.stage, start.map(|(_, yb)| vec![(x, yb)]).unwrap_or_default()));
        }
        if let Some(v) = e.cost
            && v < best
        {
            let seg = &mut segments.last_mut().expect("pushed above").1;
            if best.is_finite() {
                seg.push((x, best));
            }
            best = v;
        }
        if best.is_finite() {
            segments.last_mut().expect("pushed above").1.push((x, best));
        }
    }
    let mut shown = std::collections::BTreeSet::new();
    for (k, pts) in segments {
        let label = shown.insert(k).then(|| format!("{} — best so far", stage_label(&c.stages, k)));
        p.layers.push(Layer::Line { pts, colour: colour(k), width: 3, label });
    }
    p.legend = Some(SeriesLabelPosition::UpperRight);
    p.font = 16.0;
    Layout { title: c.title.clone(), rows: 1, cols: 1, panels: vec![Some(p)] }
}

fn with_unit(name: &str, unit: &str) -> String {
    if unit.is_empty() || unit == "-" { format!("{name} (dimensionless)") } else { format!("{name} ({unit})") }
}

fn traces(t: &Traces) -> Layout {
    let (rows, cols) = grid(t.traces.len(), 2);
    let n_stages = t.traces.iter().flat_map(|tr| tr.points.iter().map(|p| p.1 + 1)).max().unwrap_or(0);
    let panels = t
        .traces
        .iter()
        .enumerate()
        .map(|(i, tr)| {
            let x = Axis::over(tr.points.iter().map(|p| p.0 as f64 + 1.0), false);
            let y = Axis::over(tr.points.iter().map(|p| p.2).chain(tr.best), tr.log);
            let mut p = Panel::new(tr.name.clone(), "evaluation", with_unit(&tr.name, &tr.unit), x, y);
            for k in 0..n_stages {
                let pts: Vec<(f64, f64)> =
                    tr.points.iter().filter(|p| p.1 == k).map(|p| (p.0 as f64 + 1.0, p.2)).collect();
                let label = (i == 0).then(|| stage_label(&t.stages, k));
                p.layers.push(Layer::Dots { pts, colour: colour(k), alpha: 0.6, size: 3, label });
            }
            if let Some(b) = tr.best {
                p.layers.push(Layer::Line {
                    pts: vec![(x.lo, b), (x.hi, b)],
                    colour: RGBColor(0, 0, 0),
                    width: 1,
                    label: (i == 0).then(|| "best".to_string()),
                });
            }
            p.legend = (i == 0).then_some(SeriesLabelPosition::UpperRight);
            Some(p)
        })
        .collect();
    Layout { title: t.title.clone(), rows, cols, panels }
}

fn sensitivity(s: &Sensitivity) -> Layout {
    let panels = s
        .panels
        .iter()
        .map(|rp| {
            let n = rp.bars.len();
            let x = Axis::fixed(0.0, 1.45);
            let y = Axis::fixed(-0.7, n as f64 - 0.3);
            let mut p = Panel::new(rp.label.clone(), s.score_label.clone(), "parameters, highest first", x, y);
            let mut kept = Vec::new();
            let mut dropped = Vec::new();
            for (i, b) in rp.bars.iter().enumerate() {
                let yc = (n - 1 - i) as f64;
                let v = b.score.unwrap_or(0.0).clamp(0.0, 1.0);
                let r = (0.0, yc - 0.35, v, yc + 0.35);
                if b.kept {
                    kept.push(r)
                } else {
                    dropped.push(r)
                }
                let score = b.score.map_or_else(|| "n/a".into(), |v| format!("{v:.3}"));
                let note = if b.kept { "" } else { ", fixed after the screen" };
                p.layers.push(Layer::Text { at: (v + 0.02, yc), text: format!("{}  {score}{note}", b.name) });
            }
            p.layers.insert(0, Layer::Rects { rects: kept, colour: colour(0), label: Some("kept free".into()) });
            p.layers.insert(
                1,
                Layer::Rects {
                    rects: dropped,
                    colour: RGBColor(150, 150, 150),
                    label: Some("fixed at its best value".into()),
                },
            );
            p.legend = Some(SeriesLabelPosition::LowerRight);
            p.y_ticks = false;
            Some(p)
        })
        .collect::<Vec<_>>();
    let n = panels.len();
    Layout { title: s.title.clone(), rows: n.max(1), cols: 1, panels }
}

/// A rectangle (x0, y0, x1, y1) in data coordinates.
type Rect = (f64, f64, f64, f64);

/// Histogram bars (x0, 0, x1, count) of values over `bins` equal bins, and the binned range.
fn histogram(values: &[f64], bins: usize) -> (Vec<Rect>, f64, f64) {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi > lo {
        (lo, hi)
    } else {
        let pad = lo.abs().max(1.0) * 0.05;
        (lo - pad, hi + pad)
    };
    let w = (hi - lo) / bins as f64;
    let mut counts = vec![0usize; bins];
    for &v in values {
        if v.is_finite() {
            let k = (((v - lo) / w) as usize).min(bins - 1);
            counts[k] += 1;
        }
    }
    let rects =
        counts.iter().enumerate().map(|(k, &c)| (lo + k as f64 * w, 0.0, lo + (k + 1) as f64 * w, c as f64)).collect();
    (rects, lo, hi)
}

fn bins_for(n: usize) -> usize {
    ((n as f64).sqrt() as usize).clamp(8, 40)
}

fn marginal_panel(s: &Samples, i: usize, small: bool) -> Panel {
    let values: Vec<f64> = s.draws.iter().filter_map(|d| d.get(i).copied()).collect();
    let (rects, lo, hi) = histogram(&values, bins_for(values.len()));
    let top = rects.iter().map(|r| r.3).fold(1.0f64, f64::max);
    let label = s.labels.get(i).cloned().unwrap_or_default();
    // the best point may lie outside the draws: widen the axis to show it
    let best = s.best.as_ref().and_then(|b| b.get(i)).copied().filter(|b| b.is_finite());
    let x = match best {
        Some(b) if b < lo || b > hi => Axis::over([lo, hi, b], false),
        _ => Axis::fixed(lo, hi),
    };
    let mut p = Panel::new(
        if small { String::new() } else { label.clone() },
        label,
        "draws per bin",
        x,
        Axis::fixed(0.0, top * 1.12),
    );
    p.layers.push(Layer::Rects {
        rects,
        colour: colour(0),
        label: (!small).then(|| format!("{} draws", values.len())),
    });
    if let Some(b) = s.best.as_ref().and_then(|b| b.get(i)) {
        p.layers.push(Layer::Line {
            pts: vec![(*b, 0.0), (*b, top * 1.12)],
            colour: MODEL_COLOUR,
            width: 2,
            label: (!small).then(|| "best point".to_string()),
        });
    }
    p.legend = (!small).then_some(SeriesLabelPosition::UpperRight);
    p
}

fn marginals(s: &Samples) -> Layout {
    let (rows, cols) = grid(s.labels.len(), 3);
    let panels = (0..s.labels.len()).map(|i| Some(marginal_panel(s, i, false))).collect();
    Layout { title: s.title.clone(), rows, cols, panels }
}

/// Most markers in one scatter panel of a corner plot.
const SCATTER_POINTS: usize = 400;

fn corner(s: &Samples) -> Layout {
    let n = s.labels.len();
    let mut panels = Vec::with_capacity(n * n);
    for r in 0..n {
        for c in 0..n {
            if c > r {
                panels.push(None);
                continue;
            }
            if c == r {
                let mut p = marginal_panel(s, r, true);
                p.y_ticks = false;
                p.y_label = String::new();
                p.font = 13.0;
                panels.push(Some(p));
                continue;
            }
            let xs: Vec<f64> = s.draws.iter().filter_map(|d| d.get(c).copied()).collect();
            let ys: Vec<f64> = s.draws.iter().filter_map(|d| d.get(r).copied()).collect();
            // at most SCATTER_POINTS markers, evenly spread over the draws
            let step = s.draws.len().div_ceil(SCATTER_POINTS).max(1);
            let pts: Vec<(f64, f64)> =
                s.draws.iter().step_by(step).filter_map(|d| Some((*d.get(c)?, *d.get(r)?))).collect();
            let best = |k: usize| s.best.as_ref().and_then(|b| b.get(k)).copied();
            let x = Axis::over(xs.into_iter().chain(best(c)), false);
            let y = Axis::over(ys.into_iter().chain(best(r)), false);
            let mut p = Panel::new("", s.labels[c].clone(), s.labels[r].clone(), x, y);
            p.font = 13.0;
            p.layers.push(Layer::Dots { pts, colour: colour(0), alpha: 0.3, size: 2, label: None });
            if let Some(b) = &s.best
                && let (Some(&bx), Some(&by)) = (b.get(c), b.get(r))
            {
                p.layers.push(Layer::Dots {
                    pts: vec![(bx, by)],
                    colour: MODEL_COLOUR,
                    alpha: 1.0,
                    size: 5,
                    label: None,
                });
            }
            panels.push(Some(p));
        }
    }
    let title = if s.best.is_some() { format!("{} (orange: best point)", s.title) } else { s.title.clone() };
    Layout { title, rows: n.max(1), cols: n.max(1), panels }
}

fn fit(f: &FitPanels) -> Layout {
    let (rows, cols) = grid(f.panels.len(), 2);
    let k = f.value_scale;
    let panels = f
        .panels
        .iter()
        .enumerate()
        .map(|(i, sp)| {
            let data: Vec<(f64, f64)> = sp.data.iter().map(|&(t, v)| (t, v * k)).collect();
            let model: Vec<(f64, f64)> = sp.model.iter().map(|&(t, v)| (t, v * k)).collect();
            let band: Option<Vec<(f64, f64, f64)>> =
                sp.band.as_ref().map(|b| b.iter().map(|&(t, lo, hi)| (t, lo * k, hi * k)).collect());
            // the measured window (and a fifth more), where there are data: the model often runs
            // on long after the measurements end
            let t_end = data.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
            let (model, band) = if t_end.is_finite() && t_end > 0.0 {
                let limit = t_end * 1.2;
                (
                    model.into_iter().filter(|p| p.0 <= limit).collect::<Vec<_>>(),
                    band.map(|b| b.into_iter().filter(|p| p.0 <= limit).collect::<Vec<_>>()),
                )
            } else {
                (model, band)
            };
            let times = data.iter().chain(&model).map(|p| p.0);
            let values = data.iter().chain(&model).map(|p| p.1).chain(band.iter().flatten().flat_map(|b| [b.1, b.2]));
            let x = Axis::over(times, false);
            let y = Axis::over(values, false);
            let caption = match sp.x_m {
                Some(x) => format!("station {} (x = {} m)", sp.station, tick(x)),
                None => format!("station {}", sp.station),
            };
            let mut p = Panel::new(caption, "time (s)", f.value_label.clone(), x, y);
            let first = i == 0;
            if let Some(b) = band {
                p.layers.push(Layer::Band { pts: b, colour: BAND_COLOUR, label: first.then(|| f.band_label.clone()) });
            }
            p.layers.push(Layer::Dots {
                pts: data,
                colour: DATA_COLOUR,
                alpha: 0.8,
                size: 3,
                label: first.then(|| "measured".into()),
            });
            if !model.is_empty() {
                p.layers.push(Layer::Line {
                    pts: model,
                    colour: MODEL_COLOUR,
                    width: 3,
                    label: first.then(|| "model, best parameters".into()),
                });
            }
            p.legend = first.then_some(SeriesLabelPosition::UpperRight);
            Some(p)
        })
        .collect();
    Layout { title: f.title.clone(), rows, cols, panels }
}

fn boiling(b: &BoilingCurves) -> Layout {
    let (rows, cols) = grid(b.panels.len(), 3);
    let all_q = b.panels.iter().flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|q| q.1)));
    let y = Axis::over(all_q, true);
    let panels = b
        .panels
        .iter()
        .enumerate()
        .map(|(i, bp)| {
            let x = Axis::over(bp.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)), false);
            let atm = bp.pressure_pa / 101_325.0;
            let caption = format!("p = {} atm (T_sat = {} K)", tick(atm), tick(bp.t_sat_k));
            let mut p = Panel::new(caption, "wall temperature T_w (K)", "wall heat flux (W/m²)", x, y);
            for (k, s) in bp.series.iter().enumerate() {
                let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(|q| q.1 > 0.0).collect();
                p.layers.push(Layer::Line {
                    pts,
                    colour: colour(k),
                    width: 2,
                    label: Some(format!("Re_l = {}", tick(s.reynolds))),
                });
            }
            p.legend = (i == 0).then_some(SeriesLabelPosition::LowerRight);
            Some(p)
        })
        .collect();
    Layout { title: b.title.clone(), rows, cols, panels }
}

// ---------------------------------------------------------------------------------------------
// backends

pub(crate) fn svg(plot: &Plot) -> Result<String, String> {
    fonts()?;
    let l = layout(plot);
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, size(plot)).into_drawing_area();
        render(root, &l)?;
    }
    Ok(s)
}

pub(crate) fn png(plot: &Plot) -> Result<Vec<u8>, String> {
    fonts()?;
    let l = layout(plot);
    let (w, h) = size(plot);
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        render(root, &l)?;
    }
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    image::ImageEncoder::write_image(encoder, &buf, w, h, image::ColorType::Rgb8).map_err(err)?;
    Ok(out)
}
