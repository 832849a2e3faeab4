//! Every input whose cost grows without bound has a bound (docs/guide.md, "Bounds"): for each,
//! one case at the bound (accepted) and one past it (rejected with a typed error whose message
//! names the field, the value and the bound). Where building at the bound would take long in the
//! test profile, the at-bound case checks the spec or the predicted count instead, as its
//! comment says.

mod common;

#[path = "bounds/contacts.rs"]
mod contacts;
#[path = "bounds/counts.rs"]
mod counts;
#[path = "bounds/particles.rs"]
mod particles;

use bevy_cloth::ClothError;

/// Asserts that `e`'s message contains every one of `parts`.
pub fn names(e: &ClothError, parts: &[&str]) {
    let message = e.to_string();
    for part in parts {
        assert!(message.contains(part), "`{message}` does not name `{part}`");
    }
}

/// The error of `result`, which must be one.
pub fn error<T: std::fmt::Debug>(result: Result<T, ClothError>) -> ClothError {
    result.expect_err("the input is past its bound")
}
