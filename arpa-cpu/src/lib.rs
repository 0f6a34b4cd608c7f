pub use embree4_sys;
