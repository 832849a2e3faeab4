//! Writes the `character` example's asset, `assets/character/character.gltf`: a walking
//! character with a skinned cape and skirt whose vertex colours hold their target weights (see
//! `gltf.rs`). The asset is committed; run this after changing the generator, and
//! `tests/character_asset.rs` checks that the two agree.
//!
//! `cargo run --example character_asset`

mod gltf;

fn main() -> std::io::Result<()> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/character/character.gltf");
    std::fs::create_dir_all(path.parent().expect("a directory"))?;
    std::fs::write(&path, gltf::document())?;
    println!("wrote {}", path.display());
    Ok(())
}
