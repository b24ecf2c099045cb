//! A render's milestones on one clock: what waited for what on the way to the first image.
//!
//! The stage seconds of [`crate::RenderStats`] say how long each step took, not when: loading,
//! the BVH build, the GPU device's opening, its pipelines and the environment guide's walks
//! overlap on several threads, so their sum is not the wall clock and does not show which of
//! them the image waited for. A [`Timeline`] given to a [`crate::Tracer`]
//! ([`crate::Tracer::timeline`]) collects a mark at each milestone from every thread the
//! tracer runs (`device open` on the device's thread, `pipelines compiled` on its compiling
//! thread, `uploaded`, `traced`, ...), in seconds from one origin, and the render's stats carry
//! them ([`crate::RenderStats::timeline`]). The caller adds its own (`loaded`, `saved`): the
//! `render` example's `--timeline` prints them, from the process's start.
//!
//! Marking costs a lock and a push; a tracer without a timeline marks nothing.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;

/// One milestone: what happened, and when (seconds from the timeline's origin).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimelineMark {
    /// Seconds from the timeline's origin.
    pub seconds: f64,
    /// What happened (`device open`, `uploaded`, ...).
    pub event: String,
}

/// Milestones marked from any thread against one origin. A clone is the same timeline.
#[derive(Clone, Debug)]
pub struct Timeline {
    origin: Instant,
    marks: Arc<Mutex<Vec<TimelineMark>>>,
}

impl Default for Timeline {
    fn default() -> Self {
        Self::new()
    }
}

impl Timeline {
    /// A timeline whose origin is now.
    pub fn new() -> Self {
        Self::since(Instant::now())
    }

    /// A timeline whose origin is `origin` (e.g. the start of `main`).
    pub fn since(origin: Instant) -> Self {
        Self {
            origin,
            marks: Arc::new(Mutex::new(Vec::new())),
        }
    }

    /// Marks `event` now.
    pub fn mark(&self, event: impl Into<String>) {
        let seconds = self.origin.elapsed().as_secs_f64();
        let mut marks = self.marks.lock().unwrap_or_else(|e| e.into_inner());
        marks.push(TimelineMark {
            seconds,
            event: event.into(),
        });
    }

    /// The marks so far, earliest first (marks of the same instant in the order they were
    /// made).
    pub fn marks(&self) -> Vec<TimelineMark> {
        let mut marks = self.marks.lock().unwrap_or_else(|e| e.into_inner()).clone();
        marks.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        marks
    }
}

/// Marks `event` on `timeline`, if there is one.
pub(crate) fn mark(timeline: &Option<Timeline>, event: &str) {
    if let Some(t) = timeline {
        t.mark(event);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_from_several_threads_come_back_in_time_order() {
        let t = Timeline::new();
        t.mark("first");
        let u = t.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(5));
            u.mark("on another thread");
        })
        .join()
        .unwrap();
        t.mark("last");
        let marks = t.marks();
        let events: Vec<&str> = marks.iter().map(|m| m.event.as_str()).collect();
        assert_eq!(events, ["first", "on another thread", "last"]);
        assert!(marks[1].seconds >= 0.005, "{marks:?}");
        assert!(marks.windows(2).all(|w| w[0].seconds <= w[1].seconds));
    }
}
