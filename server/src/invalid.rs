//! A request field that is not valid, named by its path (`stages[0].budget`).

/// A field-level validation error.
#[derive(Debug, Clone, PartialEq)]
pub struct Invalid {
    /// Field path.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl Invalid {
    pub(crate) fn at(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self { field: Some(field.into()), message: message.into() }
    }

    /// From a calib message `field.path: what` (or `field (name): what`), taking the field from it.
    pub(crate) fn from_message(message: String) -> Self {
        Self { field: field_of(&message), message }
    }
}

/// The field path a calib/solver message starts with (`stages[0].budget: …` → `stages[0].budget`).
pub fn field_of(message: &str) -> Option<String> {
    let (head, _) = message.split_once(": ")?;
    let mut parts = head.splitn(2, ' ');
    let token = parts.next()?;
    let rest = parts.next().unwrap_or("").trim_start();
    let ok = !token.is_empty()
        && token.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '[' | ']' | '-'))
        && (rest.is_empty() || rest.starts_with('(') || rest.starts_with('='));
    ok.then(|| token.to_string())
}
