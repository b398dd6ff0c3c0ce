//! skeleton (being built)
