//! Exports: `POST /export` writes a view through `ipfn synth` into the export folder, and
//! `/exports/NAME` serves the files this server wrote, and only those.

use std::path::PathBuf;

use axum::extract::{Path, RawQuery, State};
use axum::http::StatusCode;
use axum::response::Response;
use serde_json::json;

use super::{Shared, SharedState, VIEW_PARAMS, error_reply, json_reply, only, text, with_type};
use crate::error::Result;
use crate::view::{View, parse_query, position};

/// `/exports/NAME`: a file this server exported.
pub(super) async fn exported(State(shared): SharedState, Path(name): Path<String>) -> Response {
    if !shared.exports.lock().expect("exports lock").contains(&name) {
        return text(StatusCode::NOT_FOUND, "no such export");
    }
    let kind = if name.ends_with(".exr") {
        "image/x-exr"
    } else {
        "image/png"
    };
    match std::fs::read(shared.config.export_dir.join(&name)) {
        Ok(bytes) => with_type(StatusCode::OK, kind, "no-store", bytes),
        Err(_) => text(StatusCode::NOT_FOUND, "no such export"),
    }
}

/// `POST /export?x=&y=&size=WxH&…view…`: writes the view through `ipfn synth` into the export
/// folder and answers the file's name and the command.
pub(super) async fn export(State(shared): SharedState, RawQuery(query): RawQuery) -> Response {
    let query = query.unwrap_or_default();
    let written = tokio::task::spawn_blocking(move || write_export(&shared, &query)).await;
    match written {
        Ok(Ok(answer)) => json_reply(&answer),
        Ok(Err(e)) => error_reply(&e),
        Err(e) => text(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    }
}

fn write_export(shared: &Shared, query: &str) -> Result<serde_json::Value> {
    let q = parse_query(query)?;
    only(&q, &[&VIEW_PARAMS[..], &["x", "y", "size"]].concat())?;
    let model = shared
        .source
        .current()?
        .ok_or_else(|| crate::input_error!("the run has no checkpoint yet"))?;
    let view = View::from_query(&q, &model)?;
    let size = crate::view::frame(&q, "size")?.unwrap_or([1024, 1024]);
    let at = [position(&q, "x")?, position(&q, "y")?];
    // A guided view exports its guide's frame; a 3D model's plane starts at the origin.
    let (at, size, note) = match (&view.guide, model.config.dims) {
        (Some((_, frame)), _) => ([0, 0], *frame, "a guided view exports its guide's frame"),
        (None, 3) => (
            [0, 0],
            size,
            "a 3D plane is exported from the volume's origin",
        ),
        _ => (at, size, ""),
    };
    let limit = if model.config.dims == 3 {
        crate::view::MAX_EXPORT_PLANE
    } else {
        crate::view::MAX_EXPORT_PIXELS
    };
    let [rows, cols] = view.period.unwrap_or(size);
    if rows * cols > limit {
        return Err(crate::input_error!(
            "size {cols}x{rows}: an export from the viewer paints at most {limit} pixels; use ipfn synth for larger"
        ));
    }
    let Ok(_one) = shared.export.try_lock() else {
        return Err(crate::input_error!(
            "an export is being written; wait for it"
        ));
    };
    let out = shared
        .config
        .export_dir
        .join(export_name(&view, at, [rows, cols]));
    let mut files: Vec<PathBuf> = match &model.maps {
        Some(set) => set
            .outputs(&out, Some(8))?
            .into_iter()
            .map(|o| o.path)
            .collect(),
        None => vec![out.clone()],
    };
    if view.lit(&model) {
        // After the maps, so the view's index names it.
        files.push(crate::view::lit_path(&out));
    }
    let name = |p: &PathBuf| {
        p.file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("")
            .to_string()
    };
    let ours = shared.exports.lock().expect("exports lock").clone();
    if let Some(taken) = files
        .iter()
        .find(|f| f.exists() && !ours.contains(&name(f)))
    {
        return Err(crate::input_error!(
            "{} exists and was not written by this viewer; move it, or start ipfn view with another --export-dir",
            taken.display()
        ));
    }
    let mut args = view.synth_args(&model, at, size, &out);
    let command = crate::view::command_line(&args);
    args.push("--quiet".into());
    (shared.exporter)(&args)?;
    let names: Vec<String> = files.iter().map(name).collect();
    shared
        .exports
        .lock()
        .expect("exports lock")
        .extend(names.iter().cloned());
    let shown = names.get(view.map).unwrap_or(&names[0]);
    Ok(
        json!({"file": shown, "files": names, "path": out.display().to_string(), "command": command, "note": note}),
    )
}

/// An export's file name: seed, size and place, and a short hash of the whole view, so exports
/// of different views never share a name.
fn export_name(view: &View, at: [i64; 2], [rows, cols]: [usize; 2]) -> String {
    use std::hash::{Hash, Hasher};
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    format!("{view:?}").hash(&mut hasher);
    let hash = hasher.finish() as u32;
    format!(
        "view-seed{}-{cols}x{rows}-at{}_{}-{hash:08x}.png",
        view.seed, at[0], at[1]
    )
}
