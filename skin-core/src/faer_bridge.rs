//! Private bridge between nalgebra/nalgebra-sparse and faer (zero-copy views).
