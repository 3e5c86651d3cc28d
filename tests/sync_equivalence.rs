//! DESIGN §3: in sync mode the three-process runtime is classic on-policy PPO. The same seed
//! gives bit-identical weights after k updates through shared memory as through a loop that
//! runs the simulator and learner libraries in one process (whatever the learner's thread
//! count), and (DESIGN §9) as through a sim host whose chunks and policies cross Zenoh over TCP.

use common::config::PolicySlot;
use common::{ACT_DIM, Config, OBS_DIM, Policy, PolicyLayout};
use learner_proc::{Learner, Rollout};
use sim_proc::controllers::PolicyController;
use sim_proc::driver::Driver;
use sim_proc::switching::PolicySet;
use sim_proc::terrain::Terrain;
use sim_proc::{Fleet, SharedTerrain};

mod support;

/// The in-process loop: act for T steps, update, hand the new weights to the driver. The
/// sim's seed is that of the sim with `source` id (0 beside the learner).
fn train_in_process(cfg: &Config, source: u32) -> Learner {
    let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
    let mut learner = Learner::new(cfg, layout.clone(), cfg.run.seed).expect("learner");
    let terrain = SharedTerrain::new(
        Terrain::build(&cfg.sim.terrain).expect("terrain"),
        cfg.sim.terrain.collider,
    );
    let sim_seed = common::Rng::source_seed(cfg.run.seed, source);
    let mut fleet = Fleet::new(&cfg.sim, &terrain, sim_seed);
    let policy =
        Policy::new(layout, learner.policy_weights(), cfg.ppo.obs_clip as f32).expect("policy");
    let ctrl = PolicyController::new(policy, true, sim_seed);
    let mut policies = PolicySet::new(PolicySlot::General, ctrl, learner.policy_version());
    let mut driver = Driver::new(&fleet, sim_seed);
    let (n, t) = (fleet.len(), cfg.ppo.rollout_steps(fleet.len()));
    let wanted = vec![PolicySlot::General; n];
    let mut chunk = Vec::new();
    let mut env_steps = 0;
    while env_steps < cfg.run.total_steps {
        chunk.clear();
        for _ in 0..t {
            driver.tick(&mut fleet, &policies, &wanted, &[], &mut chunk);
        }
        env_steps += (t * n) as u64;
        driver.bootstrap(&mut chunk);
        let (transitions, boot) = chunk.split_at(t * n);
        let bootstrap_obs: Vec<[f32; OBS_DIM]> = boot.iter().map(|b| b.obs).collect();
        learner
            .update(&Rollout {
                transitions,
                bootstrap_obs: &bootstrap_obs,
                episodes: &[],
            })
            .expect("update");
        let general = policies
            .get_mut(PolicySlot::General)
            .expect("general policy");
        general
            .policy
            .set_weights(&learner.policy_weights())
            .expect("same layout");
        policies.set_version(PolicySlot::General, learner.policy_version());
    }
    learner
}

/// The runtime's learner updates on two threads, the in-process loop's on one: the shards,
/// not the threads, order every sum (DESIGN §3).
#[test]
fn sync_runtime_matches_the_in_process_loop_bit_for_bit() {
    let root = support::root();
    let run_id = format!("sync-{}", std::process::id());
    let runs = root.join("target/e2e-runs");
    let mut table: toml::Table =
        toml::from_str(&std::fs::read_to_string(root.join("configs/smoke.toml")).expect("smoke"))
            .expect("smoke config");
    table
        .get_mut("ppo")
        .and_then(toml::Value::as_table_mut)
        .expect("[ppo]")
        .insert("threads".into(), toml::Value::Integer(2));
    std::fs::create_dir_all(&runs).expect("runs directory");
    let config = runs.join(format!("{run_id}.toml"));
    std::fs::write(&config, toml::to_string(&table).expect("toml")).expect("config");
    let (code, text) = support::lavatube_run(config.to_str().expect("utf-8 path"), &run_id);
    assert_eq!(code, 0, "lavatube run failed:\n{text}");
    let run = runs.join(&run_id);
    let log =
        std::fs::read_to_string(common::run_dir::log_file(&run, "learner")).expect("learner log");
    assert!(log.contains("threads=2"), "{log}");
    let mut cfg = Config::load(&config).expect("the run's config");
    let (runtime, _) =
        Learner::resume(&cfg, &run.join("checkpoints")).expect("the runtime's last checkpoint");

    cfg.ppo.threads = 1;
    let local = train_in_process(&cfg, 0);
    assert_eq!(runtime.counters(), local.counters());
    assert!(runtime.counters().update >= 3);
    let (a, b) = (runtime.policy_weights(), local.policy_weights());
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
        "weights differ after {} updates",
        local.counters().update
    );
}

#[test]
fn a_sim_behind_the_bridge_trains_the_same_weights() {
    let root = support::root();
    let cfg = Config::load(&root.join("configs/smoke.toml")).expect("smoke config");
    let hosts = support::AcrossHosts::new(
        "configs/smoke.toml",
        &format!("bridged-{}", std::process::id()),
        1,
    );
    let (learner_id, sim_id) = (
        format!("bridged-l-{}", std::process::id()),
        format!("bridged-s-{}", std::process::id()),
    );
    let learner = hosts.learner_host(&learner_id);
    let sim = hosts.sim_host(&sim_id, 1);
    let (code, sim_said) = sim.wait();
    assert_eq!(code, 0, "the sim host failed:\n{sim_said}");
    let (code, learner_said) = learner.wait();
    assert_eq!(code, 0, "the learner host failed:\n{learner_said}");
    let run = root.join("target/e2e-runs").join(&learner_id);
    let (bridged, _) = Learner::resume(&cfg, &run.join("checkpoints"))
        .expect("the learner host's last checkpoint");
    let log =
        std::fs::read_to_string(common::run_dir::log_file(&run, "learner")).expect("learner log");
    assert!(log.contains("source 1: 3 chunks (0 missed)"), "{log}");

    let local = train_in_process(&cfg, 1);
    assert_eq!(bridged.counters(), local.counters());
    let (a, b) = (bridged.policy_weights(), local.policy_weights());
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
        "weights differ after {} updates",
        local.counters().update
    );
}
