//! The asset cache: each glTF file imported once, however many entities instance it and
//! whenever they are spawned (at level load or while the game runs).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::diagnostic::LoadError;
use super::gltf_import::import_gltf;
use super::model::Asset;

/// Imported assets by file path. Paths a level writes are relative to the level's folder.
#[derive(Clone, Debug, Default)]
pub struct AssetCache {
    /// The folder relative asset paths start from (the level file's).
    pub base: PathBuf,
    by_path: HashMap<PathBuf, Arc<Asset>>,
}

impl AssetCache {
    pub fn new(base: PathBuf) -> AssetCache {
        AssetCache {
            base,
            by_path: HashMap::new(),
        }
    }

    /// The file a level's asset path names.
    pub fn resolve(&self, path: &str) -> PathBuf {
        self.base.join(path)
    }

    /// Adds an asset already imported (a loaded `Scene`'s), under its source path.
    pub fn insert(&mut self, asset: Arc<Asset>) {
        self.by_path.insert(asset.source.clone(), asset);
    }

    /// The asset at level path `path`, imported on first use.
    pub fn load(&mut self, path: &str) -> Result<Arc<Asset>, LoadError> {
        let file = self.resolve(path);
        self.load_file(&file)
    }

    /// The asset in `file`, imported on first use.
    pub fn load_file(&mut self, file: &Path) -> Result<Arc<Asset>, LoadError> {
        if let Some(asset) = self.by_path.get(file) {
            return Ok(Arc::clone(asset));
        }
        let asset = Arc::new(import_gltf(file)?);
        self.by_path.insert(file.to_owned(), Arc::clone(&asset));
        Ok(asset)
    }

    /// The files of the assets imported so far.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        self.by_path.keys().map(PathBuf::as_path)
    }

    /// Assets imported so far.
    pub fn len(&self) -> usize {
        self.by_path.len()
    }

    pub fn is_empty(&self) -> bool {
        self.by_path.is_empty()
    }
}

/// An asset as a map key: the same loaded asset, by identity (two assets read from the
/// same file but changed apart, as a test may do, are two keys). Holding the `Arc` keeps
/// the identity from being reused while the key lives.
#[derive(Clone, Debug)]
pub struct AssetKey(pub Arc<Asset>);

impl PartialEq for AssetKey {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for AssetKey {}

impl std::hash::Hash for AssetKey {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        Arc::as_ptr(&self.0).hash(state);
    }
}
