//! lsq (being built)
