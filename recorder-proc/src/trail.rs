//! Each robot's recent path: its last logged positions, started over when an episode ends
//! (the robot is placed elsewhere, and a line to there was never driven).

use std::collections::VecDeque;

/// The last `len` logged positions of every env.
#[derive(Debug, Clone)]
pub struct Trails {
    len: usize,
    points: Vec<VecDeque<[f32; 3]>>,
}

impl Trails {
    /// Trails of at most `len` points (at least 2) for `envs` envs.
    pub fn new(envs: usize, len: usize) -> Self {
        let len = len.max(2);
        Self {
            len,
            points: vec![VecDeque::with_capacity(len); envs],
        }
    }

    /// Appends a logged position of `env` (ignored for an env out of range), dropping the
    /// oldest beyond the trail's length; returns the trail.
    pub fn push(&mut self, env: usize, pos: [f32; 3]) -> Option<&VecDeque<[f32; 3]>> {
        let len = self.len;
        let trail = self.points.get_mut(env)?;
        if trail.len() == len {
            trail.pop_front();
        }
        trail.push_back(pos);
        Some(trail)
    }

    /// Forgets `env`'s path: its episode ended.
    pub fn restart(&mut self, env: usize) {
        if let Some(trail) = self.points.get_mut(env) {
            trail.clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trails_keep_the_newest_points_and_restart_per_episode() {
        let mut t = Trails::new(2, 3);
        for k in 0..5 {
            t.push(1, [k as f32, 0.0, 0.0]);
        }
        let xs: Vec<f32> = t
            .push(1, [5.0, 0.0, 0.0])
            .expect("env 1")
            .iter()
            .map(|p| p[0])
            .collect();
        assert_eq!(xs, [3.0, 4.0, 5.0]);
        t.restart(1);
        assert_eq!(t.push(1, [9.0, 0.0, 0.0]).expect("env 1").len(), 1);
        assert!(t.push(2, [0.0; 3]).is_none());
    }
}
