//! `[sim.external]`: a gym client acting for the sim (`sim.acting = "external"`, our
//! extension): how long the sim waits for it and what happens when it leaves.

use super::setting::{flag, real, settings};

settings! {
    /// The sim's side of a gym client.
    pub struct ExternalConfig {
        /// Seconds the sim waits for the client's next request, the first one included, before
        /// it gives up on the client (died or stalled).
        pub timeout_s: f64 = 30.0 => real(0.1, 86_400.0), "s", Advanced;
        /// After a client closes or is given up on, wait for the next one (unbounded) instead of
        /// ending the run.
        pub stay_up: bool = false => flag(), "", Advanced;
    }
}
