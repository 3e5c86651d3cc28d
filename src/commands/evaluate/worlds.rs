//! The worlds `lavatube evaluate` drives in: a TOML file of `[[world]]` tables, each a
//! `name` and config fields laid over the evaluation's config as a config that `extends` it
//! would be (`configs/worlds/robustness.toml`). A world of a name alone is the config's own.

use crate::error::UserError;
use common::Config;
use std::path::Path;

/// One named world: the evaluation's config with the world's fields laid over it.
#[derive(Debug, Clone)]
pub struct World {
    pub name: String,
    pub cfg: Config,
}

/// The worlds of `path` over `base`, in the file's order; a file that is not TOML, names no
/// world, holds a world without a name or with a name twice, or a field the config refuses
/// is refused in one line naming the world.
pub fn read(path: &Path, base: &Config) -> anyhow::Result<Vec<World>> {
    let refuse = |what: String| UserError(format!("worlds file {}: {what}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| refuse(e.to_string()))?;
    let File { world } = common::config::parse_toml(&text, path)?;
    if world.is_empty() {
        return Err(
            refuse("names no world: add one, e.g. `[[world]] name = \"nominal\"`".into()).into(),
        );
    }
    let mut worlds: Vec<World> = Vec::new();
    for (i, mut fields) in world.into_iter().enumerate() {
        let name = match fields.remove("name") {
            Some(toml::Value::String(name)) if !name.is_empty() => name,
            _ => return Err(refuse(format!("world {} needs a `name`", i + 1)).into()),
        };
        if worlds.iter().any(|w| w.name == name) {
            return Err(refuse(format!("world `{name}` is named twice")).into());
        }
        let cfg = base
            .overlaid(fields, path)
            .map_err(|e| refuse(format!("world `{name}`: {e}")))?;
        worlds.push(World { name, cfg });
    }
    Ok(worlds)
}

/// The file's form: a list of worlds, nothing else.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    world: Vec<toml::Table>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn worlds_of(text: &str) -> anyhow::Result<Vec<World>> {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("worlds.toml");
        std::fs::write(&path, text).expect("write");
        read(&path, &Config::default())
    }

    #[test]
    fn each_world_lays_its_fields_over_the_config_in_file_order() {
        let worlds = worlds_of(
            "[[world]]\nname = \"nominal\"\n\n[[world]]\nname = \"moon\"\nsim.gravity = 1.62\n\n\
             [[world]]\nname = \"heavy\"\n[world.sim.randomize]\nmass-scale = [1.5, 2.0]\n",
        )
        .expect("worlds");
        let names: Vec<_> = worlds.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(names, ["nominal", "moon", "heavy"]);
        assert_eq!(worlds[0].cfg, Config::default());
        assert_eq!(worlds[1].cfg.sim.gravity, 1.62);
        assert_eq!(worlds[1].cfg.sim.robot, Config::default().sim.robot);
        assert_eq!(worlds[2].cfg.sim.randomize.mass_scale, [1.5, 2.0]);
    }

    #[test]
    fn a_bad_world_is_refused_in_one_line_naming_it() {
        for (text, says) in [
            ("", "names no world"),
            ("[nominal]\n", "unknown field `nominal`"),
            ("[[world]]\nsim.gravity = 2.0\n", "world 1 needs a `name`"),
            (
                "[[world]]\nname = \"a\"\n[[world]]\nname = \"a\"\n",
                "`a` is named twice",
            ),
            (
                "[[world]]\nname = \"slick\"\nsim.friction = 0.1\n",
                "world `slick`: ",
            ),
            (
                "[[world]]\nname = \"moon\"\nsim.gravity = 0.0\n",
                "world `moon`: config field `sim.gravity`",
            ),
            (
                "[[world]]\nname = \"swapped\"\nsim.randomize.latency = [3, 1]\n",
                "`sim.randomize.latency`",
            ),
            ("[[world]\n", "worlds.toml:1"),
        ] {
            let err = worlds_of(text).expect_err(text).to_string();
            assert!(err.contains(says), "{text:?}: {err}");
            assert!(!err.contains('\n'), "{err}");
        }
    }

    #[test]
    fn the_shipped_robustness_worlds_lay_over_the_paper_config() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let paper = Config::load(&root.join("configs/paper.toml")).expect("paper.toml");
        let worlds = read(&root.join("configs/worlds/robustness.toml"), &paper).expect("worlds");
        let names: Vec<_> = worlds.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "nominal",
                "slippery",
                "heavy",
                "weak-motors",
                "latency-50ms",
                "latency-100ms",
                "slow-motors",
                "noisy-imu",
                "pushes",
                "lunar-gravity",
                "all-at-once"
            ]
        );
        assert_eq!(worlds[0].cfg, paper);
        // 50 ms and 100 ms of latency, in their worlds' physics steps.
        for (w, ms) in [(&worlds[4], 50.0), (&worlds[5], 100.0)] {
            let s = &w.cfg.sim;
            let latency = s.robot.command_latency as f64 * s.physics_dt * 1000.0;
            assert!((latency - ms).abs() < 1e-6, "{}: {latency} ms", w.name);
            assert!(
                (s.decision_dt() - 0.1).abs() < 1e-9,
                "{}: same decision step",
                w.name
            );
        }
    }
}
