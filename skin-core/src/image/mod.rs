//! image (being built)
