//! Lorenz–Mie scattering by homogeneous spheres (work in progress).
