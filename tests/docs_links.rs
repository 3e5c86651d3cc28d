//! Every relative link in README.md and docs/*.md leads somewhere: the file exists beside the
//! page that links it, and a `#anchor` names a heading of that file (GitHub's slug). Every
//! page of docs/ is a chapter of the book, listed in docs/SUMMARY.md.
//!
//! Links to http(s):// and mailto: are not followed, and nothing inside a fenced code block
//! or an inline code span is a link.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// One Markdown link `[text](target)` (or image `![alt](target)`) of a page.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Link {
    /// 1-based line of the link's target.
    line: usize,
    text: String,
    target: String,
}

/// The lines of `page` outside fenced code blocks, numbered from 1. A fence is three or more
/// backticks or tildes, indented by at most three spaces, closed by a fence of the same
/// character at least as long.
fn prose_lines(page: &str) -> Vec<(usize, &str)> {
    let mut open: Option<(char, usize)> = None;
    let mut lines = Vec::new();
    for (i, line) in page.lines().enumerate() {
        let trimmed = line.trim_start_matches(' ');
        let fence = (line.len() - trimmed.len() <= 3)
            .then(|| {
                let c = trimmed.chars().next()?;
                let run = trimmed.chars().take_while(|&x| x == c).count();
                ((c == '`' || c == '~') && run >= 3).then_some((c, run))
            })
            .flatten();
        match (open, fence) {
            (None, Some(f)) => open = Some(f),
            (Some((c, n)), Some((d, m))) if c == d && m >= n && trimmed[m..].trim().is_empty() => {
                open = None;
            }
            (None, None) => lines.push((i + 1, line)),
            _ => {}
        }
    }
    lines
}

/// `line` with its inline code spans (`` `…` ``, ``` ``…`` ```) blanked out.
fn without_code_spans(line: &str) -> String {
    let chars: Vec<char> = line.chars().collect();
    let mut out = String::with_capacity(line.len());
    let mut i = 0;
    while i < chars.len() {
        if chars[i] != '`' {
            out.push(chars[i]);
            i += 1;
            continue;
        }
        let run = chars[i..].iter().take_while(|&&c| c == '`').count();
        // The closing run: the same number of backticks, not part of a longer run.
        let close = (i + run..chars.len()).find(|&j| {
            chars[j..].iter().take_while(|&&c| c == '`').count() == run
                && (j == 0 || chars[j - 1] != '`')
        });
        match close {
            Some(j) => {
                out.extend(std::iter::repeat_n(' ', j + run - i));
                i = j + run;
            }
            None => {
                // No closing run: the backticks are literal.
                out.extend(std::iter::repeat_n('`', run));
                i += run;
            }
        }
    }
    out
}

/// The Markdown links of `page`, in order. The link text may start on an earlier line.
fn links(page: &str) -> Vec<Link> {
    let mut found = Vec::new();
    // Where the innermost `[` still open was, as the text after it.
    let mut text_start: Vec<String> = Vec::new();
    for (number, raw) in prose_lines(page) {
        let line: Vec<char> = without_code_spans(raw).chars().collect();
        let mut i = 0;
        while i < line.len() {
            match line[i] {
                '\\' => i += 1,
                '[' => text_start.push(String::new()),
                ']' if i + 1 < line.len() && line[i + 1] == '(' => {
                    let text = text_start.pop().unwrap_or_default();
                    // The target runs to the `)` that balances its `(`.
                    let mut depth = 0;
                    let mut end = None;
                    for (j, &c) in line.iter().enumerate().skip(i + 1) {
                        match c {
                            '(' => depth += 1,
                            ')' => {
                                depth -= 1;
                                if depth == 0 {
                                    end = Some(j);
                                    break;
                                }
                            }
                            _ => {}
                        }
                    }
                    if let Some(end) = end {
                        let inside: String = line[i + 2..end].iter().collect();
                        let inside = inside.trim();
                        // An optional title after the destination: `(file.md "Title")`.
                        let target = match inside.strip_prefix('<') {
                            Some(rest) => rest.split('>').next().unwrap_or_default(),
                            None => inside.split_whitespace().next().unwrap_or_default(),
                        };
                        found.push(Link {
                            line: number,
                            text: text.trim().to_string(),
                            target: target.to_string(),
                        });
                        for t in &mut text_start {
                            t.extend(&line[i..=end]);
                        }
                        i = end;
                    }
                }
                ']' => {
                    text_start.pop();
                }
                c => {
                    for t in &mut text_start {
                        t.push(c);
                    }
                }
            }
            i += 1;
        }
        for t in &mut text_start {
            t.push(' ');
        }
        // A link's text does not run on past a paragraph.
        if raw.trim().is_empty() {
            text_start.clear();
        }
    }
    found
}

/// GitHub's anchor for a heading's text: lowercase; everything but letters, digits, `_`,
/// hyphens and spaces removed (so Markdown's backticks and emphasis go too); each space a
/// hyphen.
fn slug(heading: &str) -> String {
    // A link in a heading counts by its text.
    let text: String = links(heading).iter().fold(heading.to_string(), |h, l| {
        h.replacen(&format!("]({})", l.target), "]", 1)
    });
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|&c| c.is_alphanumeric() || c == '_' || c == '-' || c == ' ')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of `page`'s ATX headings (outside fenced code), a repeated one suffixed `-1`,
/// `-2`, … as GitHub does.
fn anchors(page: &str) -> BTreeSet<String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut all = BTreeSet::new();
    for (_, line) in prose_lines(page) {
        let trimmed = line.trim_start_matches(' ');
        if line.len() - trimmed.len() > 3 {
            continue;
        }
        let level = trimmed.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&level) {
            continue;
        }
        let rest = &trimmed[level..];
        if !(rest.is_empty() || rest.starts_with(' ') || rest.starts_with('\t')) {
            continue;
        }
        // An optional closing sequence of `#`s after a space.
        let mut text = rest.trim();
        let bare = text.trim_end_matches('#');
        if bare.is_empty() || bare.ends_with(' ') {
            text = bare.trim_end();
        }
        let base = slug(text);
        let n = seen.entry(base.clone()).or_insert(0);
        all.insert(if *n == 0 {
            base.clone()
        } else {
            format!("{base}-{n}")
        });
        *n += 1;
    }
    all
}

/// `%20` and the like decoded, as a browser does before opening the file.
fn percent_decoded(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match (bytes[i], bytes.get(i + 1), bytes.get(i + 2)) {
            (b'%', Some(&h), Some(&l)) if hex(h).is_some() && hex(l).is_some() => {
                out.push((hex(h).unwrap_or(0) * 16 + hex(l).unwrap_or(0)) as u8);
                i += 3;
            }
            (b, _, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn is_external(target: &str) -> bool {
    let lower = target.to_ascii_lowercase();
    ["http://", "https://", "mailto:"]
        .iter()
        .any(|p| lower.starts_with(p))
}

/// What is wrong with `link` of the page at `page` (whose text is `text`), if anything: a
/// file that does not exist, or an anchor no heading of the target has. `read` gives a
/// Markdown file's text.
fn problem(
    page: &Path,
    text: &str,
    link: &Link,
    read: &mut dyn FnMut(&Path) -> Option<String>,
) -> Option<String> {
    if is_external(&link.target) {
        return None;
    }
    if link.target.is_empty() {
        return Some("empty link target".into());
    }
    let (path, anchor) = match link.target.split_once('#') {
        Some((p, a)) => (p, Some(a)),
        None => (link.target.as_str(), None),
    };
    let path = percent_decoded(path);
    let (file, body) = if path.is_empty() {
        (page.to_path_buf(), Some(text.to_string()))
    } else {
        let file = page.parent().unwrap_or(Path::new("")).join(&path);
        if !file.exists() {
            return Some(format!("no such file: {}", file.display()));
        }
        let body = anchor.and_then(|_| read(&file));
        (file, body)
    };
    let anchor = anchor.map(percent_decoded)?;
    let Some(body) = body else {
        return Some(format!(
            "#{anchor}: {} is not a Markdown file whose headings can be read",
            file.display()
        ));
    };
    let known = anchors(&body);
    (!known.contains(&anchor)).then(|| {
        format!(
            "#{anchor}: no heading of {} has that anchor (it has {})",
            file.display(),
            known.into_iter().collect::<Vec<_>>().join(", ")
        )
    })
}

/// README.md and every docs/*.md, sorted, relative to the repository's root.
fn pages(root: &Path) -> Vec<PathBuf> {
    let mut pages = vec![PathBuf::from("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ is readable")
        .map(|e| e.expect("a docs/ entry").path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "md"))
        .map(|p| p.strip_prefix(root).expect("under the root").to_path_buf())
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

#[test]
fn every_relative_link_and_anchor_of_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut read = |p: &Path| {
        (p.extension().is_some_and(|e| e == "md"))
            .then(|| std::fs::read_to_string(p).ok())
            .flatten()
    };
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in pages(root) {
        let text = std::fs::read_to_string(root.join(&page))
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", page.display()));
        for link in links(&text) {
            checked += 1;
            if let Some(why) = problem(&root.join(&page), &text, &link, &mut read) {
                let why = why.replace(&format!("{}/", root.display()), "");
                broken.push(format!(
                    "{}:{}: [{}]({}): {why}",
                    page.display(),
                    link.line,
                    link.text,
                    link.target
                ));
            }
        }
    }
    assert!(checked > 0, "no links found: is the scanner broken?");
    assert!(
        broken.is_empty(),
        "{} broken link(s):\n{}",
        broken.len(),
        broken.join("\n")
    );
}

#[test]
fn every_page_of_docs_is_a_chapter_of_the_summary() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let summary = std::fs::read_to_string(root.join("docs/SUMMARY.md"))
        .expect("docs/SUMMARY.md, the book's table of contents, exists");
    assert!(
        summary.lines().next() == Some("# Summary"),
        "docs/SUMMARY.md:1: must be `# Summary` (mdBook's format)"
    );
    let listed: BTreeSet<String> = links(&summary)
        .into_iter()
        .map(|l| percent_decoded(l.target.split('#').next().unwrap_or_default()))
        .collect();
    let missing: Vec<String> = pages(root)
        .into_iter()
        .filter(|p| p.starts_with("docs"))
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            (name != "SUMMARY.md" && !listed.contains(&name))
                .then(|| format!("{}: not listed in docs/SUMMARY.md", p.display()))
        })
        .collect();
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

// The checker itself: it must find what is broken, or the tests above prove nothing.

#[test]
fn links_are_found_outside_code_only() {
    let page = "See [the design](DESIGN.md#1-processes) and ![a map](img/map.png \"Map\").\n\
                `[not](a-link.md)` and [external](https://example.com).\n\
                ```sh\n[inside](fence.md)\n```\n\
                A [text that\nwraps](WRAPPED.md).\n";
    let found: Vec<(usize, String, String)> = links(page)
        .into_iter()
        .map(|l| (l.line, l.text, l.target))
        .collect();
    assert_eq!(
        found,
        [
            (1, "the design".into(), "DESIGN.md#1-processes".into()),
            (1, "a map".into(), "img/map.png".into()),
            (2, "external".into(), "https://example.com".into()),
            (7, "text that wraps".into(), "WRAPPED.md".into()),
        ]
    );
}

#[test]
fn anchors_are_githubs_slugs() {
    let page = "# lavatube: the contracts\n\
                ## §1 Processes and data flow\n\
                ## E1. Async training (`run.mode = \"async\"`)\n\
                ## Déjà vu, 2× faster!\n\
                ## Setup\n## Setup\n## Setup ##\n\
                ```\n# not a heading\n```\n\
                #not a heading either\n";
    let expected: BTreeSet<String> = [
        "lavatube-the-contracts",
        "1-processes-and-data-flow",
        "e1-async-training-runmode--async",
        "déjà-vu-2-faster",
        "setup",
        "setup-1",
        "setup-2",
    ]
    .into_iter()
    .map(String::from)
    .collect();
    assert_eq!(anchors(page), expected);
}

#[test]
fn a_missing_file_or_anchor_is_reported() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let page = root.join("docs/ARCHITECTURE.md");
    let text = "# Top\n## A part\n";
    let mut read = |p: &Path| std::fs::read_to_string(p).ok();
    let check = |target: &str, read: &mut dyn FnMut(&Path) -> Option<String>| {
        let link = Link {
            line: 1,
            text: "x".into(),
            target: target.into(),
        };
        problem(&page, text, &link, read)
    };
    assert_eq!(check("#a-part", &mut read), None);
    assert_eq!(check("DESIGN.md", &mut read), None);
    assert_eq!(check("https://example.com/nowhere", &mut read), None);
    let missing = check("NO-SUCH-PAGE.md", &mut read).expect("a missing file is reported");
    assert!(missing.contains("no such file"), "{missing}");
    let anchor = check("#no-such-part", &mut read).expect("a missing anchor is reported");
    assert!(anchor.contains("#no-such-part"), "{anchor}");
    let elsewhere = check("DESIGN.md#no-such-section", &mut read)
        .expect("a missing anchor in another file is reported");
    assert!(elsewhere.contains("DESIGN.md"), "{elsewhere}");
}
