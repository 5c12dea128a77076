//! The coordinator's counters and their Prometheus text (GET /metrics).
//!
//! Plain numbers: the coordinator bumps them under its lock and takes a [`Snapshot`] to
//! format after releasing it. Nothing here locks, reads jobs or leases itself, or does I/O.

use crate::api::JobState;

#[derive(Debug, Default, Clone)]
pub(super) struct Metrics {
    pub leases_issued: u64,
    pub leases_expired: u64,
    pub tiles_accepted: u64,
    pub tiles_rejected: u64,
    /// Renders of verified tile passes held for another worker's to compare with.
    pub tiles_held: u64,
    /// Workers set aside because their render disagreed with two others'.
    pub workers_set_aside: u64,
}

/// The counters and gauges at one moment.
pub(super) struct Snapshot {
    pub counters: Metrics,
    /// Jobs in each state, in [`JobState::ALL`]'s order.
    pub jobs: [usize; 4],
    pub leases_active: usize,
}

impl Snapshot {
    pub fn new(
        counters: &Metrics,
        states: impl Iterator<Item = JobState>,
        leases_active: usize,
    ) -> Snapshot {
        let mut jobs = [0; 4];
        for s in states {
            jobs[JobState::ALL.iter().position(|&a| a == s).expect("listed")] += 1;
        }
        Snapshot {
            counters: counters.clone(),
            jobs,
            leases_active,
        }
    }

    /// The Prometheus text exposition (version 0.0.4).
    pub fn render(&self) -> String {
        let m = &self.counters;
        let mut out = String::new();
        for (name, help, value) in [
            (
                "kiln_leases_issued_total",
                "Tile leases issued.",
                m.leases_issued,
            ),
            (
                "kiln_leases_expired_total",
                "Leases that expired without a result.",
                m.leases_expired,
            ),
            (
                "kiln_tiles_accepted_total",
                "Tile results accepted.",
                m.tiles_accepted,
            ),
            (
                "kiln_tiles_rejected_total",
                "Tile uploads rejected as corrupt.",
                m.tiles_rejected,
            ),
            (
                "kiln_tiles_held_total",
                "Renders of verified tile passes held for a second worker's.",
                m.tiles_held,
            ),
            (
                "kiln_workers_set_aside_total",
                "Workers set aside because their render disagreed with two others'.",
                m.workers_set_aside,
            ),
        ] {
            out.push_str(&format!(
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}\n"
            ));
        }
        out.push_str("# HELP kiln_jobs Jobs by state.\n# TYPE kiln_jobs gauge\n");
        for (state, n) in JobState::ALL.iter().zip(self.jobs) {
            out.push_str(&format!("kiln_jobs{{state=\"{}\"}} {n}\n", state.as_str()));
        }
        out.push_str(
            "# HELP kiln_leases_active Leases outstanding.\n# TYPE kiln_leases_active gauge\n",
        );
        out.push_str(&format!("kiln_leases_active {}\n", self.leases_active));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_is_prometheus_exposition_with_every_family() {
        let counters = Metrics {
            leases_issued: 7,
            leases_expired: 1,
            tiles_accepted: 5,
            tiles_rejected: 2,
            tiles_held: 4,
            workers_set_aside: 1,
        };
        let states = [JobState::Done, JobState::Running, JobState::Done];
        let text = Snapshot::new(&counters, states.into_iter(), 3).render();
        let expected = "\
# HELP kiln_leases_issued_total Tile leases issued.
# TYPE kiln_leases_issued_total counter
kiln_leases_issued_total 7
# HELP kiln_leases_expired_total Leases that expired without a result.
# TYPE kiln_leases_expired_total counter
kiln_leases_expired_total 1
# HELP kiln_tiles_accepted_total Tile results accepted.
# TYPE kiln_tiles_accepted_total counter
kiln_tiles_accepted_total 5
# HELP kiln_tiles_rejected_total Tile uploads rejected as corrupt.
# TYPE kiln_tiles_rejected_total counter
kiln_tiles_rejected_total 2
# HELP kiln_tiles_held_total Renders of verified tile passes held for a second worker's.
# TYPE kiln_tiles_held_total counter
kiln_tiles_held_total 4
# HELP kiln_workers_set_aside_total Workers set aside because their render disagreed with two others'.
# TYPE kiln_workers_set_aside_total counter
kiln_workers_set_aside_total 1
# HELP kiln_jobs Jobs by state.
# TYPE kiln_jobs gauge
kiln_jobs{state=\"running\"} 1
kiln_jobs{state=\"done\"} 2
kiln_jobs{state=\"failed\"} 0
kiln_jobs{state=\"cancelled\"} 0
# HELP kiln_leases_active Leases outstanding.
# TYPE kiln_leases_active gauge
kiln_leases_active 3
";
        assert_eq!(text, expected);
    }
}
