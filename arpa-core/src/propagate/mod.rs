//! Propagate (`no_std`): carrying a photon's ray differential along its path. Transfer,
//! reflection and refraction of the differentials, shading normals and their
//! differentials, normal and bump maps, Fresnel reflectance, the Lambertian shading frame, re-emission at a
//! diffuse hit, and the path classification (caustic or global map, smoothing).

pub mod classify;
pub mod differential;
pub mod fresnel;
pub mod lambertian;
pub mod normal_map;
pub mod reemission;
pub mod shading_normal;
