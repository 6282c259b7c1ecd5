//! The report's page: text escaped, the rows as a table a click on a heading sorts (a few
//! lines of script in the page), the sections put together with their style. No network: the
//! charts are inline SVG and nothing is fetched.

use std::fmt::Write as _;

use crate::runs::summary::RowView;

/// `text` safe inside HTML text and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A number cell: sorted by its value, shown to `decimals` places; empty when there is none.
fn number(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("<td data-v=\"{v}\">{v:.decimals$}</td>"),
        _ => "<td data-v=\"\"></td>".into(),
    }
}

/// The rows' table: one line per row, a link to its recording where there is one
/// (`recording(row)` gives the link's target).
pub fn rows_table(rows: &[&RowView], recording: impl Fn(&RowView) -> Option<String>) -> String {
    let mut t = String::from(
        "<table class=\"rows\"><thead><tr><th>row</th><th>variant</th><th>pair</th>\
         <th>outcome</th><th>closest to traffic, m</th><th>closest to an obstacle, m</th>\
         <th>first acted, s</th><th>achieved speedup</th><th>wall, s</th><th>recording</th>\
         <th>error</th></tr></thead><tbody>\n",
    );
    for row in rows {
        let link = recording(row).map_or_else(String::new, |href| {
            format!("<a href=\"{}\">.rrd</a>", escape(&href))
        });
        let _ = writeln!(
            t,
            "<tr class=\"{ended}\"><td>{id}</td><td>{variant}</td><td>{pair}</td>\
             <td>{ended}</td>{}{}{}{}{}<td>{link}</td><td>{error}</td></tr>",
            number(row.cpa_m, 1),
            number(row.closest_obstacle_m, 2),
            number(row.first_acted_t_s, 1),
            number(row.achieved_speedup, 1),
            number(row.wall_s, 1),
            id = escape(&row.id),
            variant = escape(&row.variant),
            pair = escape(&row.pair),
            ended = escape(&row.ended),
            error = escape(row.error.as_deref().unwrap_or("")),
        );
    }
    t + "</tbody></table>\n"
}

/// Key-value pairs as a two-column table.
pub fn pairs_table(pairs: &[(String, String)]) -> String {
    let mut t = String::from("<table class=\"meta\"><tbody>\n");
    for (k, v) in pairs {
        let _ = writeln!(t, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(v));
    }
    t + "</tbody></table>\n"
}

/// A section: its id, heading and body (already HTML).
pub fn section(id: &str, heading: &str, body: &str) -> String {
    format!(
        "<section id=\"{id}\"><h2>{}</h2>\n{body}</section>\n",
        escape(heading)
    )
}

/// A chart in a figure, or a line saying why there is none.
pub fn figure(chart: Option<String>, none: &str) -> String {
    match chart {
        Some(svg) => format!("<figure>{svg}</figure>\n"),
        None => format!("<p class=\"none\">{}</p>\n", escape(none)),
    }
}

const STYLE: &str = "body{font-family:sans-serif;margin:1.5em auto;max-width:1100px;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:2em}\
figure{margin:0.5em 0}pre{background:#f6f6f6;padding:0.7em;overflow-x:auto}\
table{border-collapse:collapse;font-size:0.85em}td,th{border:1px solid #ddd;padding:2px 6px}\
table.rows th{cursor:pointer;background:#eee;position:sticky;top:0}\
table.rows td[data-v]{text-align:right}tr.collision td:nth-child(4){color:#d62728}\
tr.nmac td:nth-child(4){color:#ff7f0e}tr.error td:nth-child(4){color:#7f7f7f}\
table.meta th{text-align:left;background:#f6f6f6}p.none{color:#777}\
figure.plan{display:inline-block;margin:0.3em;vertical-align:top;max-width:470px}\
figure.plan figcaption{font-size:0.85em}";

/// Sorts a `table.rows` by the clicked column (numbers by `data-v`, else text), again to
/// reverse.
const SCRIPT: &str = "for(const th of document.querySelectorAll('table.rows th')){\
th.addEventListener('click',()=>{const i=th.cellIndex,body=th.closest('table').tBodies[0];\
const up=th.dataset.up!=='1';th.dataset.up=up?'1':'0';\
const key=r=>{const c=r.cells[i];return c.dataset.v!==undefined?\
(c.dataset.v===''?Infinity:parseFloat(c.dataset.v)):c.textContent};\
const rows=[...body.rows].sort((a,b)=>{const x=key(a),y=key(b);\
const d=typeof x==='number'?(x===y?0:x<y?-1:1):x.localeCompare(y);return up?d:-d});\
for(const r of rows)body.appendChild(r)})}";

/// The whole page.
pub fn page(title: &str, sections: &[String]) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{t}</title><style>{STYLE}</style></head>\n<body><h1>{t}</h1>\n{}\
         <script>{SCRIPT}</script></body></html>\n",
        sections.concat(),
        t = escape(title)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markup_in_a_row_is_shown_as_text() {
        assert_eq!(
            escape("<b a=\"1\">&'"),
            "&lt;b a=&quot;1&quot;&gt;&amp;&#39;"
        );
        let row = RowView {
            id: "<script>".into(),
            ended: "pass".into(),
            cpa_m: Some(12.345),
            ..RowView::default()
        };
        let table = rows_table(&[&row], |_| None);
        assert!(table.contains("&lt;script&gt;"), "{table}");
        assert!(!table.contains("<script>"), "{table}");
        assert!(table.contains("<td data-v=\"12.345\">12.3</td>"), "{table}");
    }
}
