//! The README, CHANGELOG.md, CONTRIBUTING.md and every page of the book (`docs/`) link only to
//! files that exist, and to headings that exist in them; book pages link only within `docs/`
//! (mdBook serves nothing else), and every page of the book is in `docs/SUMMARY.md`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn book_pages(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            book_pages(&path, out);
        } else if path.extension().is_some_and(|e| e == "md") {
            out.push(path);
        }
    }
}

/// The text without fenced code blocks and inline code, where brackets are not links.
fn prose(text: &str) -> String {
    let mut out = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut code = false;
        for c in line.chars() {
            if c == '`' {
                code = !code;
            } else if !code {
                out.push(c);
            }
        }
        out.push('\n');
    }
    out
}

/// Link targets: `[text](target)`, `![alt](target "title")` and `[name]: target` lines.
fn links(text: &str) -> Vec<String> {
    let text = prose(text);
    let mut out: Vec<String> = text
        .match_indices("](")
        .filter_map(|(i, _)| {
            let rest = &text[i + 2..];
            let end = rest.find(')')?;
            let target = rest[..end].trim().trim_start_matches('<');
            let target = target.split_whitespace().next()?.trim_end_matches('>');
            Some(target.to_string())
        })
        .collect();
    for line in text.lines() {
        let line = line.trim_start();
        if line.starts_with('[')
            && let Some((_, target)) = line.split_once("]: ")
        {
            out.push(target.trim().to_string());
        }
    }
    out
}

/// A heading's anchor as mdBook and GitHub make it.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '_' | '-' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn anchors(page: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(page).unwrap();
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(slug(&line.trim_start_matches('#').replace('`', "")));
        }
    }
    out
}

#[test]
fn headings_become_anchors() {
    assert_eq!(
        slug(
            " `ipfn view`: see the plane, follow training"
                .replace('`', "")
                .as_str()
        ),
        "ipfn-view-see-the-plane-follow-training"
    );
    assert_eq!(
        links("a [b](c.md#d) `[e](f)` ![g](h.png \"t\")"),
        ["c.md#d", "h.png"]
    );
}

#[test]
fn every_link_of_the_docs_resolves() {
    let root = root();
    let docs = root.join("docs");
    let mut pages = vec![
        root.join("README.md"),
        root.join("CHANGELOG.md"),
        root.join("CONTRIBUTING.md"),
    ];
    book_pages(&docs, &mut pages);
    assert!(pages.len() > 10, "the book is found: {pages:?}");
    let mut bad = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for link in links(&text) {
            if link.starts_with("http://")
                || link.starts_with("https://")
                || link.starts_with("mailto:")
            {
                continue;
            }
            let (path, anchor) = link.split_once('#').unwrap_or((&link, ""));
            let target = if path.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(path)
            };
            let name = page.strip_prefix(&root).unwrap().display();
            let Ok(target) = target.canonicalize() else {
                bad.push(format!("{name}: broken link {link}"));
                continue;
            };
            if page.starts_with(&docs) && !target.starts_with(docs.canonicalize().unwrap()) {
                bad.push(format!(
                    "{name}: {link} leaves docs/, which mdBook does not serve"
                ));
            }
            let is_page = target.extension().is_some_and(|e| e == "md");
            if !anchor.is_empty() && is_page && !anchors(&target).contains(anchor) {
                bad.push(format!("{name}: no heading for #{anchor} in {link}"));
            }
        }
    }
    let summary = std::fs::read_to_string(docs.join("SUMMARY.md")).unwrap();
    let listed: BTreeSet<String> = links(&summary).into_iter().collect();
    for page in pages.iter().filter(|p| p.starts_with(&docs)) {
        let rel = page
            .strip_prefix(&docs)
            .unwrap()
            .to_string_lossy()
            .into_owned();
        if rel != "SUMMARY.md" && !listed.contains(&rel) {
            bad.push(format!("docs/{rel} is not in docs/SUMMARY.md"));
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}
