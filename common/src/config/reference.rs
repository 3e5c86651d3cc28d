//! The field reference, made from the declarations ([`super::setting::settings!`]):
//! docs/CONFIG.md and `lavatube check-config --explain FIELD`.

use super::setting::{Row, Setting, Tier};
use super::{AreaKind, Config, PolicySlot};

/// Every field of the config with its default, accepted values, unit, tier and doc, in
/// declaration order.
pub fn rows() -> Vec<Row> {
    let mut out = Vec::new();
    Config::default().rows("", &mut out);
    out
}

/// What `--explain KEY` prints: the field's doc, default, accepted values, unit and tier;
/// for a section (`ppo`, `sim.terrain`) one line per field. An unknown key is an error that
/// names the nearest keys.
pub fn explain(key: &str) -> Result<String, String> {
    let all = rows();
    if let Some(row) = all.iter().find(|r| r.key == key) {
        return Ok(describe(row));
    }
    let prefix = format!("{key}.");
    let section: Vec<_> = all.iter().filter(|r| r.key.starts_with(&prefix)).collect();
    if !section.is_empty() {
        let width = section.iter().map(|r| r.key.len()).max().unwrap_or(0);
        let lines: Vec<_> = section
            .iter()
            .map(|r| format!("{:<width$}  {} ({})", r.key, r.default, r.tier.name()))
            .collect();
        return Ok(lines.join("\n") + "\n");
    }
    let leaf = key.rsplit('.').next().unwrap_or(key);
    let near: Vec<_> = all
        .iter()
        .filter(|r| r.key.rsplit('.').next() == Some(leaf) || r.key.contains(key))
        .map(|r| r.key.as_str())
        .take(5)
        .collect();
    Err(if near.is_empty() {
        format!("no config field `{key}` (`--explain run` lists a section's fields)")
    } else {
        format!("no config field `{key}`; did you mean {}?", near.join(", "))
    })
}

fn describe(row: &Row) -> String {
    let unit = if row.unit.is_empty() { "-" } else { row.unit };
    format!(
        "{key} ({tier})\n  {doc}\n  default: {default}\n  accepts: {domain}\n  unit:    {unit}\n",
        key = row.key,
        tier = row.tier.name(),
        doc = row.text(),
        default = row.default,
        domain = row.domain,
    )
}

/// docs/CONFIG.md: one table per section, every field with its default, accepted values,
/// unit, tier and doc.
pub fn markdown() -> String {
    let mut md = String::from(
        "# Configuration reference\n\n\
         Every field of a run config, generated from the declarations in `common/src/config/` \
         (`lavatube check-config --reference` prints this page; `lavatube check-config \
         --explain FIELD` prints one field). A config is TOML, kebab-case, with unknown keys \
         refused; a field not set keeps its default. How the files fit together: \
         [Configuration](CONFIGURATION.md).\n\n\
         Tiers: **essential**, what most runs set; **advanced**, tuning of the learner, the \
         physics and the processes; **research**, the paper's interpretations and the \
         extensions an experiment switches. `[]` in a key marks the fields of a list's items.\n",
    );
    let all = rows();
    let parent = |row: &Row| row.key.rsplit_once('.').map_or("", |(p, _)| p).to_owned();
    let mut sections: Vec<String> = Vec::new();
    for row in &all {
        let p = parent(row);
        if !sections.contains(&p) {
            sections.push(p);
        }
    }
    for section in &sections {
        md.push_str(&format!(
            "\n## {section}\n\n| field | default | accepts | unit | tier | what it does |\n|---|---|---|---|---|---|\n"
        ));
        for row in all.iter().filter(|r| &parent(r) == section) {
            let leaf = &row.key[section.len() + usize::from(!section.is_empty())..];
            md.push_str(&format!(
                "| `{leaf}` | `{default}` | {domain} | {unit} | {tier} | {doc} |\n",
                default = cell(&row.default),
                domain = cell(&row.domain.to_string()),
                unit = cell(row.unit),
                tier = row.tier.name(),
                doc = cell(&row.text()),
            ));
        }
    }
    let count = |t: Tier| all.iter().filter(|r| r.tier == t).count();
    md.push_str(&format!(
        "\n{} fields: {} essential, {} advanced, {} research.\n",
        all.len(),
        count(Tier::Essential),
        count(Tier::Advanced),
        count(Tier::Research)
    ));
    md.push_str(&kinds_table());
    md
}

/// The areas and slots that `sim.envs`, `sim.terrain.areas`, `run.learners` and the wire
/// name, from the one table of terrain kinds.
fn kinds_table() -> String {
    let mut md = String::from(
        "\n## Terrain kinds\n\nThe areas `sim.envs` and `sim.terrain.areas` name, their code in \
         telemetry, track and CSV files (`area`, the estimator's class), and each kind's policy \
         slot (`run.learners`, its index on the wire; `general` is 0) and specialist's label in \
         reports. Declared once, in `common/src/config/kinds.rs`.\n\n\
         | area | code | policy slot | slot index | specialist | colour |\n|---|---:|---|---:|---|---|\n",
    );
    for area in AreaKind::ALL {
        let slot = PolicySlot::for_class(area.code());
        let [r, g, b] = area.colour();
        md.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | `#{r:02x}{g:02x}{b:02x}` |\n",
            area.name(),
            area.code(),
            slot.map_or("-".into(), |s| format!("`{}`", s.name())),
            slot.map_or("-".into(), |s| s.index().to_string()),
            area.model().unwrap_or("- (the course)"),
        ));
    }
    md
}

/// Text for one cell of a Markdown table.
fn cell(text: &str) -> String {
    text.replace('|', "\\|").replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::setting::Domain;

    #[test]
    fn explain_prints_a_fields_doc_default_and_range() {
        let text = explain("ppo.clip-coef").expect("declared");
        assert_eq!(
            text,
            "ppo.clip-coef (advanced)\n  Surrogate clip ε.\n  default: 0.2\n  accepts: [0.000001, 1]\n  unit:    -\n"
        );
        let section = explain("ppo").expect("a section");
        assert!(section.contains("ppo.clip-coef") && section.contains("ppo.shard-size"));
        let err = explain("ppo.clip").expect_err("no such field");
        assert!(err.contains("ppo.clip-coef"), "{err}");
    }

    #[test]
    fn every_field_has_a_range_or_choices_and_a_doc() {
        for row in rows() {
            assert!(
                !matches!(row.domain, Domain::Form("a section")),
                "{} declares no range or choices",
                row.key
            );
            assert!(!row.text().is_empty(), "{} has no doc", row.key);
        }
    }

    #[test]
    fn every_default_passes_its_own_check() {
        Config::default()
            .check("", &super::super::setting::form("the whole config"))
            .expect("defaults in range");
    }

    /// docs/CONFIG.md is this module's output; `LAVATUBE_BLESS=1` writes it anew.
    #[test]
    fn the_reference_page_is_current() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/CONFIG.md");
        let made = markdown();
        if std::env::var_os("LAVATUBE_BLESS").is_some() {
            std::fs::write(&path, &made).expect("write docs/CONFIG.md");
        }
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            on_disk == made,
            "docs/CONFIG.md is stale: run `LAVATUBE_BLESS=1 cargo test -p common the_reference_page_is_current`"
        );
    }
}
