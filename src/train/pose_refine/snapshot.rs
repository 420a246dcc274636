//! [`PoseSnapshot`]: the pose corrections at one step, without Adam's moments, as a record
//! keeps them (the depth prior's switch records the cameras its stereo used).

use super::{camera_models, PoseState};
use crate::scene::Camera;
use crate::train::pose::PoseCorrection;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

impl PoseState {
    /// The corrections alone, without Adam's moments: what the cameras are at this step.
    pub fn snapshot(&self) -> PoseSnapshot {
        PoseSnapshot {
            views: self
                .corrections
                .iter()
                .map(|c| [c.omega.x, c.omega.y, c.omega.z, c.t.x, c.t.y, c.t.z])
                .collect(),
            focal: self.focal.iter().map(|f| f[0]).collect(),
        }
    }
}

/// The pose corrections at one step, as a record can keep them (the depth prior's switch
/// records the cameras its stereo used, so that a resumed run rebuilds the same ones).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseSnapshot {
    /// `[views][6]`: `ω` (so(3), radians) then `t` (normalised units) of each training view.
    pub views: Vec<[f64; 6]>,
    /// `[camera models]`: the focal's log scale `φ` (empty when the focal is not learned).
    pub focal: Vec<f64>,
}

impl PoseSnapshot {
    /// The cameras with these corrections applied, as [`PoseState::corrected`]; `None` when
    /// the counts do not fit `cameras` (views, or camera models when the focal is learned) or a
    /// value is not finite.
    pub fn corrected(&self, cameras: &[Camera]) -> Option<Vec<Camera>> {
        let finite = self
            .views
            .iter()
            .flatten()
            .chain(&self.focal)
            .all(|v| v.is_finite());
        let models = camera_models(cameras).1;
        if !finite
            || self.views.len() != cameras.len()
            || !(self.focal.is_empty() || self.focal.len() == models)
        {
            return None;
        }
        let mut s = PoseState::new(self.views.len(), self.focal.len());
        for (c, v) in s.corrections.iter_mut().zip(&self.views) {
            *c = PoseCorrection {
                omega: Vector3::new(v[0], v[1], v[2]),
                t: Vector3::new(v[3], v[4], v[5]),
            };
        }
        for (f, &phi) in s.focal.iter_mut().zip(&self.focal) {
            f[0] = phi;
        }
        Some(s.corrected(cameras))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A snapshot (the corrections a record keeps) gives the state's cameras, also after a
    /// round trip through JSON, and refuses what does not fit the cameras.
    #[test]
    fn a_snapshot_gives_the_states_cameras_and_refuses_what_does_not_fit() {
        let cams = crate::scene::camera::tests::orbit(3, 0.7, |_| 1.0);
        let mut s = PoseState::new(3, 1);
        s.corrections[0].omega = Vector3::new(0.01, -0.02, 0.03);
        s.corrections[2].t = Vector3::new(0.1, 0.0, -0.05);
        s.m[1][0] = 0.5;
        s.focal[0] = [0.04, 0.3, 0.1];
        let snap = s.snapshot();
        assert_ne!(s.corrected(&cams), cams);
        assert_eq!(snap.corrected(&cams), Some(s.corrected(&cams)));
        let text = serde_json::to_string(&snap).unwrap();
        let back: PoseSnapshot = serde_json::from_str(&text).unwrap();
        assert_eq!(back.corrected(&cams), Some(s.corrected(&cams)));
        assert!(snap.corrected(&cams[..2]).is_none());
        let mut two_focal = snap.clone();
        two_focal.focal.push(0.0);
        assert!(two_focal.corrected(&cams).is_none());
        let mut nan = snap.clone();
        nan.views[1][4] = f64::NAN;
        assert!(nan.corrected(&cams).is_none());
        // Without a learned focal, the imported intrinsics.
        let mut no_focal = snap;
        no_focal.focal.clear();
        s.focal.clear();
        assert_eq!(no_focal.corrected(&cams), Some(s.corrected(&cams)));
    }
}
