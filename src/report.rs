//! A training run as the page shows it: `metrics.csv` as columns, the preview images, the
//! config, and whether the run is running, stopped or finished; and `report.html`, the same
//! without a server.

use std::fs::{File, TryLockError};
use std::path::Path;

use serde_json::{Value, json};

use crate::error::Result;

/// The page (HTML with its CSS and script), served by `ipfn view` at `/` and written as
/// `report.html`.
pub const PAGE_HTML: &str = include_str!("view/page.html");
/// The page's script: the plane, the controls, the plots.
pub const PAGE_JS: &str = include_str!("view/page.js");

/// Metrics rows sent to the page at most (longer runs are thinned evenly; scored rows are kept).
pub const MAX_POINTS: usize = 2000;

/// Whether a run trains now: `running` while a process holds its `run.lock`, else `finished`
/// when its planned iterations are done, else `stopped`.
pub fn run_state(run_dir: &Path, iteration: u64) -> &'static str {
    if let Ok(file) = File::open(run_dir.join("run.lock")) {
        // A shared lock fails while `ipfn train` holds the exclusive one; taken, it is released
        // at once (the trainer retries its lock briefly, so it never sees this one).
        if let Err(TryLockError::WouldBlock) = file.try_lock_shared() {
            return "running";
        }
    }
    let planned = std::fs::read_to_string(run_dir.join("config.toml"))
        .ok()
        .and_then(|text| text.parse::<toml::Table>().ok())
        .and_then(|t| t.get("iterations").and_then(toml::Value::as_integer));
    match planned {
        Some(total) if iteration >= total as u64 => "finished",
        _ => "stopped",
    }
}

/// `metrics.csv` as named columns (numbers; `null` where a row has no value, such as the score
/// of an unscored iteration). Rows cut short by a write in progress are skipped.
pub fn read_metrics(run_dir: &Path) -> (Vec<String>, Vec<Vec<Option<f64>>>) {
    let text = std::fs::read_to_string(run_dir.join("metrics.csv")).unwrap_or_default();
    let mut lines = text.lines();
    let names: Vec<String> = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows: Vec<Vec<Option<f64>>> = lines
        .filter_map(|line| {
            let cells: Vec<&str> = line.split(',').collect();
            if cells.len() > names.len() || cells[0].parse::<u64>().is_err() {
                return None;
            }
            // A row from before a column was added (a resumed run) has none of it.
            let value = |i: usize| cells.get(i).and_then(|c| c.parse().ok());
            Some((0..names.len()).map(value).collect())
        })
        .collect();
    (names, rows)
}

/// Every `step`-th row, the last row and every row with a score, so at most about
/// [`MAX_POINTS`] plus the scored rows.
fn thin(rows: Vec<Vec<Option<f64>>>, score: Option<usize>) -> Vec<Vec<Option<f64>>> {
    let step = rows.len().div_ceil(MAX_POINTS).max(1);
    let last = rows.len().saturating_sub(1);
    rows.into_iter()
        .enumerate()
        .filter(|(i, row)| i % step == 0 || *i == last || score.is_some_and(|s| row[s].is_some()))
        .map(|(_, row)| row)
        .collect()
}

/// The preview images' names (`iter-NNNNNN.png`), oldest first.
pub fn previews(run_dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(run_dir.join("previews"))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| is_preview_name(n))
        .collect();
    names.sort();
    names
}

/// Whether `name` is a preview's name: `iter-` digits `.png`, nothing else (no paths).
pub fn is_preview_name(name: &str) -> bool {
    name.strip_prefix("iter-")
        .and_then(|n| n.strip_suffix(".png"))
        .is_some_and(|d| !d.is_empty() && d.len() <= 12 && d.bytes().all(|b| b.is_ascii_digit()))
}

/// The run as the page shows it: state, metrics columns, previews, config text.
pub fn snapshot(run_dir: &Path) -> Value {
    let (names, rows) = read_metrics(run_dir);
    let iteration = rows.last().and_then(|r| r[0]).unwrap_or(0.0) as u64;
    let score = names.iter().position(|n| n == "sifid");
    let rows = thin(rows, score);
    let mut columns = serde_json::Map::new();
    for (i, name) in names.iter().enumerate() {
        let column: Vec<Option<f64>> = rows.iter().map(|r| r[i]).collect();
        columns.insert(name.clone(), json!(column));
    }
    json!({
        "folder": run_dir.display().to_string(),
        "state": run_state(run_dir, iteration),
        "iteration": iteration,
        "metrics": columns,
        "previews": previews(run_dir),
        "config": std::fs::read_to_string(run_dir.join("config.toml")).unwrap_or_default(),
        "best": run_dir.join("best.ipfn").is_file(),
    })
}

/// The page with `data` embedded as `window.IPFN_REPORT`, so it shows the run without a
/// server (previews by their paths relative to the run folder).
pub fn report_html(data: &Value) -> String {
    // Inside <script>, "</" and "<!--" must not appear; JSON escapes keep the text equal.
    let json = data
        .to_string()
        .replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026");
    // The script first: the data, inserted last, is never searched for markers.
    PAGE_HTML.replace("/*IPFN_SCRIPT*/", PAGE_JS).replacen(
        "/*IPFN_DATA*/",
        &format!("window.IPFN_REPORT = {json};"),
        1,
    )
}

/// Writes `report.html` into the run folder (atomically): the metrics plots, previews and config
/// of the run as it stands, in `state` (`finished` or `stopped`: the trainer, which still holds
/// the run's lock, says).
pub fn write_report(run_dir: &Path, state: &str) -> Result<()> {
    let mut data = snapshot(run_dir);
    data["state"] = json!(state);
    let html = report_html(&data);
    crate::io::write_atomic(&run_dir.join("report.html"), html.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preview_names_are_digits_only() {
        assert!(is_preview_name("iter-000100.png"));
        for bad in [
            "iter-.png",
            "../x.png",
            "iter-1/../../a.png",
            "iter-1.png.png",
            "x.png",
        ] {
            assert!(!is_preview_name(bad), "{bad}");
        }
    }

    #[test]
    fn metrics_are_thinned_but_keep_scores_and_the_last_row() {
        let rows: Vec<Vec<Option<f64>>> = (0..10_000)
            .map(|i| vec![Some(i as f64), (i % 1000 == 7).then_some(1.0)])
            .collect();
        let kept = thin(rows, Some(1));
        assert!(kept.len() <= MAX_POINTS + 1 + 10, "{}", kept.len()); // every 5th, the last, the scored
        assert_eq!(kept.last().unwrap()[0], Some(9999.0));
        assert_eq!(kept.iter().filter(|r| r[1].is_some()).count(), 10);
    }

    #[test]
    fn rows_from_before_a_column_was_added_read_as_without_it() {
        let dir = tempfile::tempdir().unwrap();
        let csv = "iteration,sifid,repeat\n1,,\n100,9.5\n200,8.5,0.25\n3,1,2,3\n";
        std::fs::write(dir.path().join("metrics.csv"), csv).unwrap();
        let (names, rows) = read_metrics(dir.path());
        assert_eq!(names, ["iteration", "sifid", "repeat"]);
        let row = |i: usize| rows[i].clone();
        assert_eq!(row(0), [Some(1.0), None, None]);
        assert_eq!(row(1), [Some(100.0), Some(9.5), None]);
        assert_eq!(row(2), [Some(200.0), Some(8.5), Some(0.25)]);
        assert_eq!(rows.len(), 3, "a row longer than the header is dropped");
    }

    #[test]
    fn report_data_cannot_close_the_script() {
        let config = "</script><script>alert(1)</script> /*IPFN_SCRIPT*/ /*IPFN_DATA*/";
        let html = report_html(&json!({ "config": config }));
        assert!(!html.contains("</script><script>alert"));
        assert_eq!(html.matches("window.IPFN_REPORT = ").count(), 1);
        assert_eq!(html.matches("function plot(").count(), 1, "the script once");
    }
}
