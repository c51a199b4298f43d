//! cryofit-plots: the figures of a calibration, drawn with plotters as SVG text or PNG bytes.
//!
//! Inputs are plain data ([`Plot`] and the structs it holds): evaluation histories, parameter
//! traces, sensitivity rankings, posterior draws, model and measured time series, boiling curves.
//! Nothing here reads or writes files, knows a database or HTTP, or runs a model: callers gather
//! the numbers and decide where the bytes go. Text is laid out with DejaVu Sans, built into the
//! crate (`fonts/`, with its licence), so PNGs look the same on every machine.
//!
//! [`index_html`] writes the page that shows a set of figures; [`escape_html`] is the escaping it
//! (and the coordinator's dashboard) uses.

#![warn(missing_docs)]

mod draw;
mod html;

pub use html::{IndexEntry, escape_html, index_html};

/// Why a figure could not be drawn.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("drawing `{figure}`: {message}")]
pub struct PlotError {
    /// The figure's title.
    pub figure: String,
    /// What went wrong.
    pub message: String,
}

/// One evaluation of a calibration as the history plots see it.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Its number in the calibration's order (0-based).
    pub index: usize,
    /// The stage that asked for it.
    pub stage: usize,
    /// Its cost; `None` when it failed.
    pub cost: Option<f64>,
}

/// Best cost against evaluations, coloured by stage.
#[derive(Debug, Clone, PartialEq)]
pub struct CostHistory {
    /// Figure title.
    pub title: String,
    /// Legend label of each stage (`stage 1: cmaes`), by stage index.
    pub stages: Vec<String>,
    /// Every evaluation, in order.
    pub evaluations: Vec<Evaluation>,
}

/// Values of one parameter over the evaluations.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Parameter name.
    pub name: String,
    /// Its unit (empty for a dimensionless parameter).
    pub unit: String,
    /// Draw the value axis logarithmically (log-scaled parameters).
    pub log: bool,
    /// (evaluation index, stage, value), in order.
    pub points: Vec<(usize, usize, f64)>,
    /// The best value found, drawn as a horizontal line.
    pub best: Option<f64>,
}

/// Parameter traces: one panel per parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Traces {
    /// Figure title.
    pub title: String,
    /// Legend label of each stage, by stage index.
    pub stages: Vec<String>,
    /// One per parameter.
    pub traces: Vec<Trace>,
}

/// One parameter of a screening stage's ranking.
#[derive(Debug, Clone, PartialEq)]
pub struct RankedBar {
    /// Parameter name.
    pub name: String,
    /// Score normalised to the largest (0–1); `None` when it could not be computed.
    pub score: Option<f64>,
    /// Whether the screen kept it free for the later stages.
    pub kept: bool,
}

/// The ranking of one screening stage.
#[derive(Debug, Clone, PartialEq)]
pub struct RankingPanel {
    /// Panel title (`stage 1: sensitivity`).
    pub label: String,
    /// Highest first.
    pub bars: Vec<RankedBar>,
}

/// Sensitivity ranking bar charts, one panel per screening stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensitivity {
    /// Figure title.
    pub title: String,
    /// What the score is (axis label).
    pub score_label: String,
    /// One per screening stage.
    pub panels: Vec<RankingPanel>,
}

/// Posterior draws of some parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Samples {
    /// Figure title.
    pub title: String,
    /// Axis label of each parameter (name and unit).
    pub labels: Vec<String>,
    /// Draws, each a value per parameter in `labels` order.
    pub draws: Vec<Vec<f64>>,
    /// The best point, marked on every panel.
    pub best: Option<Vec<f64>>,
}

/// Model against data at one station.
#[derive(Debug, Clone, PartialEq)]
pub struct StationPanel {
    /// Station name.
    pub station: String,
    /// Its position along the line, m.
    pub x_m: Option<f64>,
    /// Measured (time, value).
    pub data: Vec<(f64, f64)>,
    /// Model at the best parameters (time, value).
    pub model: Vec<(f64, f64)>,
    /// Posterior-predictive band (time, lower, upper).
    pub band: Option<Vec<(f64, f64, f64)>>,
}

/// One measured quantity of one experiment, a panel per station.
#[derive(Debug, Clone, PartialEq)]
pub struct FitPanels {
    /// Figure title.
    pub title: String,
    /// Value axis label with unit (`wall temperature (K)`).
    pub value_label: String,
    /// Multiply values by this before drawing (1e-3 to draw Pa as kPa).
    pub value_scale: f64,
    /// What the band is (`5–95 % posterior predictive`).
    pub band_label: String,
    /// One per station.
    pub panels: Vec<StationPanel>,
}

/// Wall heat flux against wall temperature at one liquid Reynolds number.
#[derive(Debug, Clone, PartialEq)]
pub struct BoilingSeries {
    /// Liquid Reynolds number.
    pub reynolds: f64,
    /// (wall temperature K, heat flux W/m²).
    pub points: Vec<(f64, f64)>,
}

/// Boiling curves at one pressure.
#[derive(Debug, Clone, PartialEq)]
pub struct BoilingPanel {
    /// Pressure, Pa.
    pub pressure_pa: f64,
    /// Saturation temperature there, K.
    pub t_sat_k: f64,
    /// One per Reynolds number.
    pub series: Vec<BoilingSeries>,
}

/// The boiling curve of the closure set at several pressures and Reynolds numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct BoilingCurves {
    /// Figure title.
    pub title: String,
    /// One per pressure.
    pub panels: Vec<BoilingPanel>,
}

/// A figure's data.
#[derive(Debug, Clone, PartialEq)]
pub enum Plot {
    /// See [`CostHistory`].
    CostHistory(CostHistory),
    /// See [`Traces`].
    Traces(Traces),
    /// See [`Sensitivity`].
    Sensitivity(Sensitivity),
    /// Histograms of each parameter's draws.
    Marginals(Samples),
    /// Pairwise scatter of the draws with the marginals on the diagonal.
    Corner(Samples),
    /// See [`FitPanels`].
    Fit(FitPanels),
    /// See [`BoilingCurves`].
    Boiling(BoilingCurves),
}

impl Plot {
    /// The figure's title.
    pub fn title(&self) -> &str {
        match self {
            Plot::CostHistory(p) => &p.title,
            Plot::Traces(p) => &p.title,
            Plot::Sensitivity(p) => &p.title,
            Plot::Marginals(p) | Plot::Corner(p) => &p.title,
            Plot::Fit(p) => &p.title,
            Plot::Boiling(p) => &p.title,
        }
    }

    /// Size in pixels (width, height).
    pub fn size(&self) -> (u32, u32) {
        draw::size(self)
    }

    /// Draws the figure as an SVG document.
    pub fn svg(&self) -> Result<String, PlotError> {
        draw::svg(self).map_err(|message| PlotError { figure: self.title().to_string(), message })
    }

    /// Draws the figure as PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        draw::png(self).map_err(|message| PlotError { figure: self.title().to_string(), message })
    }
}

/// A figure to show: its file name stem, what it shows, and its data or why it is missing.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// File name stem (`cost-history`); the files are `<name>.svg` and `<name>.png`.
    pub name: String,
    /// Heading.
    pub title: String,
    /// The data, or the reason the figure is skipped (`no MCMC stage ran`).
    pub plot: Result<Plot, String>,
}
