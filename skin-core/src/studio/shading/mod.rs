//! Lights and Lambertian shading (in progress).
