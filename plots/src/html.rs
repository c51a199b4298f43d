//! The index page of a report and HTML escaping.

use std::fmt::Write as _;

/// Escapes `&`, `<`, `>`, `"` and `'` for HTML text and attribute values.
pub fn escape_html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// One figure of a report's index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IndexEntry {
    /// File name stem: the page shows `<name>.svg` and links `<name>.png`.
    pub name: String,
    /// Heading.
    pub title: String,
    /// Why the figure is missing; `None` when its files were written.
    pub skipped: Option<String>,
}

/// The `index.html` of a report: a heading, a few lines about the calibration, and every figure
/// (or the note saying why it is missing), in order. Self-contained: no script, no external style.
pub fn index_html(title: &str, facts: &[String], entries: &[IndexEntry]) -> String {
    let mut s = String::new();
    let t = escape_html(title);
    let _ = write!(
        s,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>\
         body{{font-family:'DejaVu Sans',sans-serif;margin:2em auto;max-width:1100px;color:#222}}\
         img{{max-width:100%;border:1px solid #ddd}}figure{{margin:2em 0}}.skip{{color:#8a5a00}}\
         nav a{{margin-right:1em}}</style></head>\n<body>\n<h1>{t}</h1>\n"
    );
    if !facts.is_empty() {
        s.push_str("<ul>\n");
        for f in facts {
            let _ = writeln!(s, "<li>{}</li>", escape_html(f));
        }
        s.push_str("</ul>\n");
    }
    s.push_str("<nav>");
    for e in entries {
        let _ = write!(s, "<a href=\"#{}\">{}</a>", escape_html(&e.name), escape_html(&e.title));
    }
    s.push_str("</nav>\n");
    for e in entries {
        let (n, et) = (escape_html(&e.name), escape_html(&e.title));
        match &e.skipped {
            None => {
                let _ = writeln!(
                    s,
                    "<figure id=\"{n}\"><h2>{et}</h2><img src=\"{n}.svg\" alt=\"{et}\">\
                     <figcaption><a href=\"{n}.svg\">SVG</a> · <a href=\"{n}.png\">PNG</a></figcaption></figure>"
                );
            }
            Some(why) => {
                let _ = writeln!(
                    s,
                    "<section id=\"{n}\"><h2>{et}</h2><p class=\"skip\">Not drawn: {}</p></section>",
                    escape_html(why)
                );
            }
        }
    }
    s.push_str("</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup() {
        assert_eq!(escape_html("<a href=\"x\">&'</a>"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;");
    }

    #[test]
    fn index_shows_figures_and_notes() {
        let html = index_html(
            "NBS <quick>",
            &["best cost 12".into()],
            &[
                IndexEntry { name: "cost-history".into(), title: "Cost".into(), skipped: None },
                IndexEntry {
                    name: "posterior".into(),
                    title: "Posterior".into(),
                    skipped: Some("no MCMC stage".into()),
                },
            ],
        );
        assert!(html.contains("<title>NBS &lt;quick&gt;</title>"));
        assert!(html.contains("<img src=\"cost-history.svg\""));
        assert!(html.contains("href=\"cost-history.png\""));
        assert!(html.contains("Not drawn: no MCMC stage"));
        assert!(!html.contains("posterior.svg"));
    }
}
