//! Generalised advantage estimation over a `[steps, envs]` rollout (SPEC S6: γ, λ).
//!
//! Done flags follow the transition record: `terminated`/`truncated` say the episode ended
//! *after* this step, so the next row of the same env starts a new episode. A terminated step
//! has no future value. A truncated step was cut by the time limit, not by the task, so its
//! future is still worth `V(final_obs)`: [`bootstrap_truncated`] folds `γ·V(final_obs)` into
//! its reward first, and from then on it is treated like a terminal step (the next row belongs
//! to another episode, so neither its value nor its advantage may leak back).

/// Adds `γ·V(final_obs)` to the reward of every truncated, non-terminated step.
/// `final_values[i]` is only read where `truncated[i] && !terminated[i]`.
pub fn bootstrap_truncated(
    rewards: &mut [f32],
    terminated: &[bool],
    truncated: &[bool],
    final_values: &[f32],
    gamma: f32,
) {
    for (i, r) in rewards.iter_mut().enumerate() {
        if truncated[i] && !terminated[i] {
            *r += gamma * final_values[i];
        }
    }
}

/// Advantages and returns, each `[steps, envs]` row-major like the inputs.
pub struct Gae {
    pub advantages: Vec<f32>,
    pub returns: Vec<f32>,
}

/// CleanRL's backward recursion. `rewards`, `values`, `ended` are `[steps, envs]`; `ended` is
/// `terminated || truncated` after the step; `next_values` is `[envs]`, the value of each env's
/// observation after the last step (used only where that step did not end an episode).
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    ended: &[bool],
    next_values: &[f32],
    gamma: f32,
    lambda: f32,
) -> Gae {
    let envs = next_values.len();
    let n = rewards.len();
    debug_assert!(envs > 0 && n.is_multiple_of(envs) && values.len() == n && ended.len() == n);
    let steps = n / envs;
    let mut advantages = vec![0.0f32; n];
    let mut lastgaelam = vec![0.0f32; envs]; // [envs]
    for t in (0..steps).rev() {
        for e in 0..envs {
            let i = t * envs + e;
            let nextnonterminal = if ended[i] { 0.0 } else { 1.0 };
            let nextvalues = if t + 1 == steps {
                next_values[e]
            } else {
                values[i + envs]
            };
            let delta = rewards[i] + gamma * nextvalues * nextnonterminal - values[i];
            lastgaelam[e] = delta + gamma * lambda * nextnonterminal * lastgaelam[e];
            advantages[i] = lastgaelam[e];
        }
    }
    let returns = advantages.iter().zip(values).map(|(a, v)| a + v).collect();
    Gae {
        advantages,
        returns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-6
    }

    /// One env, three steps, γ = 0.5, λ = 0.5, values 1, 2, 3, bootstrap value 4.
    /// The recursion worked by hand:
    /// - nothing ends: δ2 = 1 + 0.5·4 − 3 = 0, δ1 = 1 + 0.5·3 − 2 = 0.5, δ0 = 1 + 0.5·2 − 1 = 1;
    ///   A2 = 0, A1 = 0.5, A0 = 1 + 0.25·0.5 = 1.125.
    #[test]
    fn gae_without_episode_ends() {
        let g = gae(&[1.0; 3], &[1.0, 2.0, 3.0], &[false; 3], &[4.0], 0.5, 0.5);
        assert!(
            close(g.advantages[0], 1.125)
                && close(g.advantages[1], 0.5)
                && close(g.advantages[2], 0.0)
        );
        assert!(close(g.returns[0], 2.125) && close(g.returns[1], 2.5) && close(g.returns[2], 3.0));
    }

    /// The same rollout with the episode ending after step 1.
    /// - terminated: δ1 = 1 − 2 = −1 (no future), A1 = −1; δ0 = 1 + 0.5·2 − 1 = 1,
    ///   A0 = 1 + 0.25·(−1) = 0.75; step 2 is a new episode: A2 = 0.
    /// - truncated with V(final_obs) = 6: the reward becomes 1 + 0.5·6 = 4, δ1 = 4 − 2 = 2,
    ///   A1 = 2, A0 = 1 + 0.25·2 = 1.5; step 2 unchanged.
    #[test]
    fn terminated_has_no_future_but_truncated_bootstraps() {
        let values = [1.0, 2.0, 3.0];
        let ended = [false, true, false];
        let final_values = [0.0, 6.0, 0.0];

        let mut rewards = [1.0; 3];
        bootstrap_truncated(
            &mut rewards,
            &[false, true, false],
            &[false; 3],
            &final_values,
            0.5,
        );
        assert_eq!(rewards, [1.0; 3], "terminated steps are not bootstrapped");
        let g = gae(&rewards, &values, &ended, &[4.0], 0.5, 0.5);
        assert!(
            close(g.advantages[0], 0.75)
                && close(g.advantages[1], -1.0)
                && close(g.advantages[2], 0.0)
        );

        let mut rewards = [1.0; 3];
        bootstrap_truncated(&mut rewards, &[false; 3], &ended, &final_values, 0.5);
        assert_eq!(rewards, [1.0, 4.0, 1.0]);
        let g = gae(&rewards, &values, &ended, &[4.0], 0.5, 0.5);
        assert!(
            close(g.advantages[0], 1.5)
                && close(g.advantages[1], 2.0)
                && close(g.advantages[2], 0.0)
        );
    }

    #[test]
    fn both_flags_count_as_terminated() {
        let mut rewards = [1.0];
        bootstrap_truncated(&mut rewards, &[true], &[true], &[100.0], 0.9);
        assert_eq!(rewards, [1.0]);
    }

    /// Two envs interleaved `[step][env]`: each env's recursion sees only its own column.
    #[test]
    fn envs_are_independent_columns() {
        // env 0: values 1, 2, next 4; env 1: values 0, 0, ends after step 0, next 10.
        let g = gae(
            &[1.0, 1.0, 1.0, 1.0],
            &[1.0, 0.0, 2.0, 0.0],
            &[false, true, false, false],
            &[4.0, 10.0],
            0.5,
            0.5,
        );
        // env 0: δ1 = 1 + 2 − 2 = 1, A1 = 1; δ0 = 1 + 1 − 1 = 1, A0 = 1 + 0.25 = 1.25.
        // env 1: δ1 = 1 + 5 − 0 = 6, A1 = 6; δ0 = 1 − 0 = 1 (ended), A0 = 1.
        assert!(close(g.advantages[0], 1.25) && close(g.advantages[2], 1.0));
        assert!(close(g.advantages[1], 1.0) && close(g.advantages[3], 6.0));
    }
}
