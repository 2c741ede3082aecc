//! Load time: everything that reads or writes asset and level files.
//!
//! Owns glTF import (`gltf_import`) into the asset model (`model`), animation sampling over
//! that model (`animation`), the level format
//! (`level`), loading a level or a bare glTF into one `Scene` (`world`), the cache that imports each
//! asset file once (`assets`), validation with
//! `file:line:column` diagnostics (`diagnostic`, `source_map`), and the generators that
//! write Gloam's own assets (`gltf_export`, `kit` with its textures' `kit_surfaces`, and the sounds' `sound_kit`). The editor saves through this module;
//! no other module touches asset or level files.

pub mod animation;
pub mod assets;
pub mod diagnostic;
pub mod files;
pub mod gltf_export;
pub mod gltf_import;
pub mod kit;
pub mod kit_surfaces;
pub mod level;
pub mod model;
pub mod sound_kit;
pub mod source_map;
pub mod watch;
pub mod world;

pub use assets::{AssetCache, AssetKey};
pub use diagnostic::{Diagnostic, LoadError, Pointer};
pub use gltf_import::import_gltf;
pub use level::Level;
pub use model::Asset;
pub use world::Scene;
