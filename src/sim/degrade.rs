//! The `degrade` effect: image degradations `KIND:q` (the paper's appendix, implemented in
//! [`crate::augment::Degradation`]), applied to each rendered view after exposure and clipping,
//! in the listed order, each with its own random stream per view
//! ([`super::render`]: seeded by scene seed, view and position in the list).

use super::SimError;
pub use crate::augment::Degradation;

/// Parses every `KIND:q` of `effects.degrade`, naming the entry at fault.
pub fn parse_all(list: &[String]) -> Result<Vec<Degradation>, SimError> {
    list.iter()
        .enumerate()
        .map(|(i, spec)| {
            spec.parse::<Degradation>().map_err(|e| SimError::Invalid {
                key: format!("effects.degrade[{i}]"),
                problem: format!("'{spec}': {e}"),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_bad_ones_are_named() {
        let ok = parse_all(&["gaussian:0.1".into(), "motion-blur:5".into()]).unwrap();
        assert_eq!(ok.len(), 2);
        assert_eq!(ok[1].to_string(), "motion-blur:5");
        let err = parse_all(&["speckle:0.2".into(), "blur:3".into()])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("effects.degrade[1]") && err.contains("blur:3"),
            "{err}"
        );
        assert!(parse_all(&[]).unwrap().is_empty());
    }
}
