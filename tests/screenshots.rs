//! Checks the screenshots that `scripts/screenshots.sh` renders of the windowed examples (CI runs
//! it under Xvfb with Mesa's software Vulkan): each picture exists, is not blank or background-only,
//! shows cloth where the scene puts it, differs from the scene's starting pose where the cloth
//! moves, and matches a reference picture (`tests/data/screenshots/`, 8×8-pixel block means)
//! within a tolerance. `UPDATE_SCREENSHOT_REFERENCES=1` rewrites the references from the current
//! pictures, for a deliberate change of a scene.
//!
//! These tests need the pictures, so they are ignored by a plain `cargo test`;
//! `scripts/test-all.sh` renders them and then runs `cargo test --test screenshots -- --ignored`.

use std::path::PathBuf;

struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
}

/// The screenshot `name` that `scripts/screenshots.sh` rendered.
fn load(name: &str) -> Picture {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("target/screenshots/{name}.png"));
    load_png(&path, "run scripts/screenshots.sh first")
}

/// The picture in the PNG file at `path`; `hint` says how to make a missing one.
fn load_png(path: &std::path::Path, hint: &str) -> Picture {
    let file =
        std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}; {hint}", path.display()));
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    let channels = info.color_type.samples();
    assert!(channels >= 3, "expected colour, got {:?}", info.color_type);
    let rgb = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    Picture {
        width: info.width as usize,
        height: info.height as usize,
        rgb,
    }
}

/// Red-dominant pixels: the fabric texture is red plaid (lit or in shade); the blue-grey sky, the
/// grey ground and the black shadows are not.
fn is_cloth([r, g, b]: [u8; 3]) -> bool {
    let (r, g, b) = (r as f32, g as f32, b as f32);
    r >= 30.0 && r > 1.6 * g && r > 1.6 * b
}

/// Fraction of cloth pixels in the rectangle given as fractions of the picture.
fn cloth_fraction(p: &Picture, rect: (f32, f32, f32, f32)) -> f32 {
    fraction_where(p, rect, |i| is_cloth(p.rgb[i]))
}

/// Fraction of the pixels in the rectangle (fractions of `p`'s size) whose index in `p.rgb`
/// satisfies `hit`.
fn fraction_where(
    p: &Picture,
    (x0, y0, x1, y1): (f32, f32, f32, f32),
    hit: impl Fn(usize) -> bool,
) -> f32 {
    let (xa, xb) = (
        (x0 * p.width as f32) as usize,
        (x1 * p.width as f32) as usize,
    );
    let (ya, yb) = (
        (y0 * p.height as f32) as usize,
        (y1 * p.height as f32) as usize,
    );
    let hits: usize = (ya..yb)
        .flat_map(|y| (xa..xb).map(move |x| y * p.width + x))
        .filter(|i| hit(*i))
        .count();
    hits as f32 / ((xb - xa) * (yb - ya)) as f32
}

fn assert_not_blank(p: &Picture) {
    let mut distinct: Vec<[u8; 3]> = p.rgb.iter().step_by(97).copied().collect();
    distinct.sort();
    distinct.dedup();
    assert!(
        distinct.len() > 50,
        "only {} distinct colours: blank frame",
        distinct.len()
    );
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn hanging_cloth_shows_the_cloth_above_the_ground() {
    let p = load("hanging_cloth");
    assert_eq!((p.width, p.height), (1280, 720));
    assert_not_blank(&p);
    // The scene frames the hanging cloth in the upper middle of the picture.
    let cloth = cloth_fraction(&p, (0.4, 0.2, 0.7, 0.5));
    assert!(
        cloth > 0.5,
        "only {:.0}% cloth pixels where it hangs",
        cloth * 100.0
    );
    let corners =
        cloth_fraction(&p, (0.0, 0.0, 0.1, 0.1)) + cloth_fraction(&p, (0.9, 0.9, 1.0, 1.0));
    assert!(
        corners < 0.05,
        "cloth colour in the picture corners: {corners}"
    );
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn subdivision_compare_shows_three_rules_at_four_levels() {
    let p = load("subdivision_compare");
    assert_not_blank(&p);
    // Each rule has its own colour (green, orange, blue): all three rows must be on screen.
    let count = |f: fn([u8; 3]) -> bool| {
        p.rgb.iter().filter(|c| f(**c)).count() as f32 / p.rgb.len() as f32
    };
    let green = count(|[r, g, b]| g as f32 > 1.3 * r as f32 && g as f32 > 1.2 * b as f32 && g > 40);
    let orange =
        count(|[r, g, b]| r as f32 > 1.3 * g as f32 && g as f32 > 1.3 * b as f32 && r > 60);
    // Stricter for blue: the sky is pale blue (about 158, 184, 209).
    let blue = count(|[r, g, b]| b as f32 > 1.6 * r as f32 && b as f32 > 1.3 * g as f32 && b > 60);
    for (name, f) in [
        ("Original (green)", green),
        ("Enhanced (orange)", orange),
        ("Tuned (blue)", blue),
    ] {
        assert!(
            f > 0.01,
            "{name} covers only {:.2}% of the picture",
            f * 100.0
        );
    }
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn drape_shows_the_cloth_over_the_sphere() {
    let p = load("drape");
    assert_not_blank(&p);
    // The cloth lies on the sphere in the middle of the picture, between the two panels.
    let cloth = cloth_fraction(&p, (0.4, 0.3, 0.6, 0.4));
    assert!(
        cloth > 0.4,
        "only {:.0}% cloth pixels over the sphere",
        cloth * 100.0
    );
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn flag_shows_the_flag_beside_its_pole() {
    let p = load("flag");
    assert_not_blank(&p);
    // The flag flies to the right of the pole, in the upper middle of the picture.
    let flag = cloth_fraction(&p, (0.42, 0.35, 0.55, 0.55));
    assert!(flag > 0.5, "only {:.0}% flag pixels", flag * 100.0);
    let left = cloth_fraction(&p, (0.3, 0.3, 0.37, 0.6));
    assert!(left < 0.05, "flag colour left of the pole: {left}");
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn tablecloth_covers_the_table_and_hangs_above_the_floor() {
    let p = load("tablecloth");
    assert_not_blank(&p);
    // The cloth covers the table top and its skirt in the middle of the picture.
    let cloth = cloth_fraction(&p, (0.42, 0.42, 0.62, 0.6));
    assert!(
        cloth > 0.5,
        "only {:.0}% cloth pixels over the table",
        cloth * 100.0
    );
    // Below the skirt the table's foot shows: the cloth did not fall through to the floor.
    let foot = cloth_fraction(&p, (0.4, 0.75, 0.6, 0.82));
    assert!(foot < 0.05, "cloth colour at the table's foot: {foot}");
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn character_wears_its_cape_where_the_camera_follows_it() {
    let p = load("character");
    assert_not_blank(&p);
    // The camera follows the walking character: its cape covers its back in the middle of the
    // picture (a cloth left where the character started would be out of the frame by now).
    let cape = cloth_fraction(&p, (0.46, 0.3, 0.52, 0.55));
    assert!(
        cape > 0.5,
        "only {:.0}% cloth pixels on its back",
        cape * 100.0
    );
    // Nothing red beside the character.
    let beside =
        cloth_fraction(&p, (0.35, 0.3, 0.42, 0.6)) + cloth_fraction(&p, (0.6, 0.3, 0.7, 0.6));
    assert!(beside < 0.05, "cloth colour beside the character: {beside}");
}

/// The crates' wood: orange-brown, red over green over blue (and not the fabric's red).
fn is_wood([r, g, b]: [u8; 3]) -> bool {
    let (r, g, b) = (r as f32, g as f32, b as f32);
    r > 90.0
        && g > 60.0
        && b < 110.0
        && r > 1.15 * g
        && g > 1.15 * b
        && !is_cloth([r as u8, g as u8, b as u8])
}

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn avian_playground_holds_the_crates_in_the_hammock_and_drapes_the_terrain() {
    let p = load("avian_playground");
    assert_not_blank(&p);
    // The hammock, upper middle left, with the crates that fell into it (they start above the
    // picture's top edge).
    let hammock = (0.32, 0.28, 0.56, 0.46);
    let cloth = cloth_fraction(&p, hammock);
    assert!(cloth > 0.3, "only {:.0}% hammock pixels", cloth * 100.0);
    let wood = fraction_where(&p, (0.32, 0.3, 0.45, 0.46), |i| is_wood(p.rgb[i]));
    assert!(
        wood > 0.3,
        "only {:.0}% crate pixels in the hammock",
        wood * 100.0
    );
    // Nothing fell through onto the ground below it.
    let below = (0.32, 0.6, 0.55, 0.85);
    let fallen = fraction_where(&p, below, |i| is_wood(p.rgb[i]) || is_cloth(p.rgb[i]));
    assert!(
        fallen < 0.02,
        "crate or cloth colour under the hammock: {fallen}"
    );
    // The sheet lies on the terrain, lower right.
    let sheet = cloth_fraction(&p, (0.6, 0.55, 0.82, 0.7));
    assert!(
        sheet > 0.5,
        "only {:.0}% sheet pixels on the terrain",
        sheet * 100.0
    );
}

/// Fraction of pixels in the rectangle (fractions of the picture) whose colour differs between
/// `a` and `b` by more than `MOVED` (summed over the channels).
fn changed_fraction(a: &Picture, b: &Picture, rect: (f32, f32, f32, f32)) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    fraction_where(a, rect, |i| {
        let (p, q) = (a.rgb[i], b.rgb[i]);
        (0..3).map(|c| p[c].abs_diff(q[c]) as u32).sum::<u32>() > MOVED
    })
}

/// A colour change (summed over the channels) that counts as a pixel having changed: well above
/// what rasterising the same scene twice gives.
const MOVED: u32 = 48;

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn laundry_piles_the_cloths_on_the_ball() {
    let p = load("laundry");
    assert_not_blank(&p);
    // The cloths cover the top of the ball in the middle of the picture...
    let pile = cloth_fraction(&p, (0.44, 0.4, 0.6, 0.52));
    assert!(
        pile > 0.6,
        "only {:.0}% cloth pixels on the ball",
        pile * 100.0
    );
    // ...and its lower half shows: they rest on it rather than falling past it.
    let below = cloth_fraction(&p, (0.45, 0.6, 0.55, 0.66));
    assert!(
        below < 0.05,
        "cloth colour on the ball's lower half: {below}"
    );
}

/// The middle of the picture, between the examples' panels (the inspector on the left, the
/// drape's scene panel on the right), whose numbers change from frame to frame.
const SCENE: (f32, f32, f32, f32) = (0.31, 0.0, 0.73, 1.0);

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn every_simulated_example_moves_its_cloth() {
    // Each example is pictured in its starting pose (simulated time held still until then) and
    // 1.5 s later. A cloth that never moved leaves the scene as it was (the light and camera do
    // not move; the character's camera follows it). Each simulated example changes several times
    // the 3% asked for (CHANGELOG.md, 2026-11-24); subdivision_compare, which
    // simulates nothing, is left out.
    for name in [
        "hanging_cloth",
        "drape",
        "flag",
        "tablecloth",
        "character",
        "avian_playground",
        "laundry",
        "inflatables",
        "tearing",
        "crowd",
    ] {
        let changed = changed_fraction(&load(&format!("{name}_start")), &load(name), SCENE);
        assert!(
            changed > 0.03,
            "{name}: only {:.1}% of the scene changed in 1.5 s",
            changed * 100.0
        );
    }
}

/// Side of the square blocks a picture is averaged over for its reference.
const BLOCK: usize = 8;

/// The picture's mean colour over each `BLOCK` × `BLOCK` block.
fn block_means(p: &Picture) -> Picture {
    let (width, height) = (p.width / BLOCK, p.height / BLOCK);
    let mut rgb = Vec::with_capacity(width * height);
    for by in 0..height {
        for bx in 0..width {
            let mut sum = [0u32; 3];
            for y in by * BLOCK..(by + 1) * BLOCK {
                for x in bx * BLOCK..(bx + 1) * BLOCK {
                    for (s, v) in sum.iter_mut().zip(p.rgb[y * p.width + x]) {
                        *s += v as u32;
                    }
                }
            }
            rgb.push(sum.map(|s| (s / (BLOCK * BLOCK) as u32) as u8));
        }
    }
    Picture { width, height, rgb }
}

fn reference_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("tests/data/screenshots/{name}.png"))
}

fn save_reference(name: &str, p: &Picture) {
    let path = reference_path(name);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut encoder = png::Encoder::new(file, p.width as u32, p.height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let data: Vec<u8> = p.rgb.iter().flatten().copied().collect();
    encoder
        .write_header()
        .unwrap()
        .write_image_data(&data)
        .unwrap();
}

/// How far a block of the scene may differ from its reference (the largest channel difference)
/// before it counts as different, and how many blocks may: rasterising the same frame again
/// differs by a level or two; a cloth in another place, shape or colour moves whole blocks.
const BLOCK_TOLERANCE: u8 = 24;
const DIFFERENT_BLOCKS: f32 = 0.02;

#[test]
#[ignore = "needs target/screenshots from scripts/screenshots.sh (run by scripts/test-all.sh)"]
fn every_example_matches_its_reference_picture() {
    let update = std::env::var_os("UPDATE_SCREENSHOT_REFERENCES").is_some();
    let mut failures = Vec::new();
    for name in [
        "hanging_cloth",
        "subdivision_compare",
        "drape",
        "flag",
        "tablecloth",
        "character",
        "avian_playground",
        "laundry",
        "inflatables",
        "tearing",
        "crowd",
    ] {
        let now = block_means(&load(name));
        if update {
            save_reference(name, &now);
            continue;
        }
        let reference = load_png(
            &reference_path(name),
            "UPDATE_SCREENSHOT_REFERENCES=1 writes it",
        );
        assert_eq!((reference.width, reference.height), (now.width, now.height));
        let reference = reference.rgb;
        let (x0, x1) = (
            (SCENE.0 * now.width as f32) as usize,
            (SCENE.2 * now.width as f32) as usize,
        );
        let (mut blocks, mut different) = (0, 0);
        for y in 0..now.height {
            for x in x0..x1 {
                let (a, b) = (now.rgb[y * now.width + x], reference[y * now.width + x]);
                let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap();
                blocks += 1;
                different += usize::from(d > BLOCK_TOLERANCE);
            }
        }
        let fraction = different as f32 / blocks as f32;
        println!(
            "{name}: {:.2}% of the scene's blocks differ from the reference",
            fraction * 100.0
        );
        if fraction > DIFFERENT_BLOCKS {
            failures.push(format!("{name}: {:.1}% of blocks differ", fraction * 100.0));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
