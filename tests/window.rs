//! The real window: `gloam play` under Xvfb with Mesa's software Vulkan (lavapipe), a
//! screenshot of the X display, and the same frames rendered headless for comparison.
//!
//! Needs `Xvfb`, ImageMagick's `import` and `xdotool` (.ci/run installs them). Without them
//! the test skips with a notice, except under CI, where it fails.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use gloam::frame::Engine;
use gloam::render::RenderSettings;
use gloam::render::hdr::tone_map;
use gloam::scene::world::Scene;

const WIDTH: u32 = 128;
const HEIGHT: u32 = 128;
const FRAMES: u32 = 6;

fn have(program: &str) -> bool {
    Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {program}"))
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Kills the child when dropped, so a failing assertion leaves no Xvfb or window behind.
struct Reaped(Child);

impl Drop for Reaped {
    /// SIGTERM first, so Xvfb removes its socket and lock files; SIGKILL if it lingers.
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .stderr(Stdio::null())
            .status();
        for _ in 0..50 {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn gloam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_gloam"))
}

#[test]
fn play_without_a_display_is_one_line_pointing_to_headless_commands() {
    // `gloam play`, and `gloam LEVEL`, which is `gloam play LEVEL`.
    for args in [&["play"][..], &["levels/first-light.ron"]] {
        let output = gloam()
            .args(args)
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .current_dir(common::repo())
            .output()
            .unwrap();
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains("gloam render"), "{stderr}");
    }
}

/// A virtual X display for one test: Xvfb (reaped when dropped), its name, and a private
/// runtime folder; None (after a notice) when the tools are missing outside CI.
fn x_display(test: &str) -> Option<(Reaped, String, std::path::PathBuf)> {
    let missing: Vec<&str> = ["Xvfb", "import", "xdotool"]
        .into_iter()
        .filter(|p| !have(p))
        .collect();
    if !missing.is_empty() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install {missing:?} (.ci/run does)"
        );
        println!("notice: skipping the window test, {missing:?} not installed");
        return None;
    }
    let dir = common::scratch_dir(test);
    let runtime = dir.join("runtime");
    std::fs::create_dir_all(&runtime).unwrap();
    std::fs::set_permissions(
        &runtime,
        std::os::unix::fs::PermissionsExt::from_mode(0o700),
    )
    .unwrap();
    // Xvfb picks a free display and writes its number to stdout once it accepts clients
    // (-displayfd), so no guessing at numbers or polling for sockets.
    let mut xvfb = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1280x800x24",
            "-nolisten",
            "tcp",
            // An X server resets when its last client leaves, closing the connections of
            // any client that joined meanwhile: the test's xdotool polls come and go while
            // gloam connects, and a reset there kills the window under test.
            "-noreset",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start Xvfb");
    let mut announced = String::new();
    BufReader::new(xvfb.stdout.take().unwrap())
        .read_line(&mut announced)
        .expect("Xvfb display number");
    let xvfb = Reaped(xvfb);
    let display = format!(":{}", announced.trim());
    assert!(display.len() > 1, "Xvfb did not announce a display");
    Some((xvfb, display, dir))
}

/// `gloam` on `display`, with its own config and cache folders under `dir`.
fn windowed(display: &str, dir: &std::path::Path) -> Command {
    let mut command = gloam();
    command
        .env("DISPLAY", display)
        .env("XDG_RUNTIME_DIR", dir.join("runtime"))
        .env("GLOAM_CONFIG_DIR", dir.join("config"))
        .env("GLOAM_CACHE_DIR", dir.join("cache"))
        .env_remove("WAYLAND_DISPLAY")
        .current_dir(common::repo());
    command
}

/// Lines of a child's output, as they come.
fn lines_of(output: impl std::io::Read + Send + 'static) -> std::sync::mpsc::Receiver<String> {
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(output).lines().map_while(Result::ok) {
            let _ = sender.send(line);
        }
    });
    receiver
}

/// Gives window `id` the keyboard focus (real key presses go to the focused window: winit
/// ignores synthetic events), trying again while it settles on the display.
fn focus_window(display: &str, id: &str) {
    // Up to 20 s: the window tests run side by side, and the editor's keeps both cores busy.
    for _ in 0..200 {
        let focused = Command::new("xdotool")
            .args(["windowfocus", "--sync", id])
            .env("DISPLAY", display)
            .stderr(Stdio::null())
            .status()
            .unwrap();
        if focused.success() {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("the window never took the focus");
}

/// Runs xdotool on `display` (it must succeed); what it printed, trimmed.
fn xdotool_on(display: &str, args: &[&str]) -> String {
    let output = Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .unwrap();
    assert!(output.status.success(), "xdotool {args:?}");
    String::from_utf8_lossy(&output.stdout).trim().to_owned()
}

/// Takes a screenshot of window `id` into `shot`, and counts the pixels in the rectangle
/// `(xs, ys)` whose colour passes `test`.
fn pixels_in_shot(
    display: &str,
    id: &str,
    shot: &std::path::Path,
    (xs, ys): (std::ops::Range<u32>, std::ops::Range<u32>),
    test: impl Fn(&[u8; 3]) -> bool,
) -> usize {
    let status = Command::new("import")
        .args(["-window", id])
        .arg(shot)
        .env("DISPLAY", display)
        .status()
        .unwrap();
    assert!(status.success());
    let image = image::open(shot).unwrap().to_rgb8();
    xs.flat_map(|x| ys.clone().map(move |y| (x, y)))
        .filter(|&(x, y)| test(&image.get_pixel(x, y).0))
        .count()
}

/// The window named Gloam on `display`, shown by `gloam` (which must not have exited).
fn gloam_window(display: &str, gloam: &mut Child) -> String {
    for _ in 0..600 {
        if let Ok(Some(status)) = gloam.try_wait() {
            panic!("gloam exited ({status}) before its window showed");
        }
        let found = Command::new("xdotool")
            .args(["search", "--onlyvisible", "--name", "Gloam"])
            .env("DISPLAY", display)
            .output()
            .unwrap();
        let id = String::from_utf8_lossy(&found.stdout)
            .lines()
            .next()
            .unwrap_or_default()
            .trim()
            .to_owned();
        if !id.is_empty() {
            return id;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("no window named Gloam on the display");
}

#[test]
fn the_window_shows_the_headless_frame() {
    let Some((_xvfb, display, dir)) = x_display("window") else {
        return;
    };
    // No pictures folder in this home: F12's screenshots go to the data folder.
    let data = dir.join("data");
    let mut window = Reaped(
        windowed(&display, &dir)
            .env("HOME", dir.join("home"))
            .env("XDG_DATA_HOME", &data)
            .args([
                "play",
                "levels/cornell.ron",
                "--width",
                &WIDTH.to_string(),
                "--height",
                &HEIGHT.to_string(),
            ])
            .args(["--frames", &FRAMES.to_string(), "--linger-seconds", "60"])
            // The raw, progressively accumulated film at a fixed resolution: what the
            // headless render below computes exactly.
            .args(["--filter", "raw", "--fixed-resolution"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start gloam play"),
    );
    // Wait for `ready` (the frames are rendered and on screen).
    let receiver = lines_of(window.0.stdout.take().unwrap());
    let ready = receiver.recv_timeout(Duration::from_secs(180));
    if !matches!(&ready, Ok(line) if line.starts_with("ready")) {
        let _ = window.0.kill();
        let output = window.0.wait_with_output_or_stderr();
        panic!("the window never became ready ({ready:?}); stderr: {output}");
    }
    // Let the compositor-less X server catch the latest present, then take the shot.
    std::thread::sleep(Duration::from_millis(500));
    let id = gloam_window(&display, &mut window.0);
    let shot = dir.join("window.png");
    let status = Command::new("import")
        .args(["-window", &id, shot.to_str().unwrap()])
        .env("DISPLAY", &display)
        .status()
        .unwrap();
    assert!(status.success(), "import failed");

    // F12 writes what the window shows and the linear film under it, and says where.
    focus_window(&display, &id);
    let pressed = Command::new("xdotool")
        .args(["key", "F12"])
        .env("DISPLAY", &display)
        .status()
        .unwrap();
    assert!(pressed.success(), "xdotool key F12");
    let said = receiver
        .recv_timeout(Duration::from_secs(60))
        .expect("a line saying where the screenshot went");
    let folder = data.join("gloam/screenshots");
    let png = folder.join("cornell-001.png");
    let exr = folder.join("cornell-001.exr");
    assert_eq!(
        said,
        format!("screenshot: {} and {}", png.display(), exr.display())
    );
    drop(window);

    // The same frames, headless.
    let scene = Scene::load(&common::repo().join("levels/cornell.ron")).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(WIDTH, HEIGHT));
    for _ in 0..FRAMES {
        engine.advance(0.0);
    }
    let expected: Vec<[u8; 3]> = engine
        .image()
        .pixels
        .iter()
        .map(|p| tone_map(*p, 1.0))
        .collect();

    // The window is the buffer scaled up; sample an image of it at each buffer pixel's
    // centre. The HUD's corner line covers the top rows: compare below them.
    let compare = |image: &image::RgbImage| {
        let (shot_width, shot_height) = image.dimensions();
        let scale = (shot_width / WIDTH).min(shot_height / HEIGHT).max(1);
        let (offset_x, offset_y) = (
            (shot_width - WIDTH * scale) / 2,
            (shot_height - HEIGHT * scale) / 2,
        );
        let (mut difference, mut brightness, mut count) = (0.0f64, 0.0f64, 0.0f64);
        for y in 20..HEIGHT {
            for x in 0..WIDTH {
                let shown = image
                    .get_pixel(
                        offset_x + x * scale + scale / 2,
                        offset_y + y * scale + scale / 2,
                    )
                    .0;
                let wanted = expected[(y * WIDTH + x) as usize];
                for channel in 0..3 {
                    difference += (shown[channel] as f64 - wanted[channel] as f64).abs();
                    brightness += shown[channel] as f64;
                    count += 1.0;
                }
            }
        }
        (difference / count, brightness / count, scale)
    };
    let screenshot = image::open(&shot).unwrap().into_rgb8();
    let (shot_width, shot_height) = screenshot.dimensions();
    let (difference, brightness, scale) = compare(&screenshot);
    println!(
        "window {shot_width}x{shot_height} (scale {scale}): mean |difference| {difference:.2} of 255, mean level {brightness:.1}"
    );
    assert!(
        brightness > 20.0,
        "the window is (nearly) black: {brightness}"
    );
    assert!(
        difference < 4.0,
        "the window differs from the headless frame by {difference} of 255 on average"
    );

    // The screenshot's PNG is what the window shows, at its size (HUD and all), the EXR
    // the film's radiance: below the HUD the PNG is the headless frame as the window
    // scales it, the EXR exactly the film.
    let png = image::open(&png).unwrap().into_rgb8();
    assert_eq!(png.dimensions(), (shot_width, shot_height));
    let (difference, _, _) = compare(&png);
    assert!(
        difference < 2.0,
        "the screenshot differs from the headless frame by {difference} of 255 on average"
    );
    let film = gloam::render::hdr::HdrImage::read_exr(&exr).unwrap();
    assert_eq!(
        film.pixels,
        engine.image().pixels,
        "the EXR is the linear film"
    );
}

/// Bare `gloam` opens the main menu: a broken settings file is named in one line with its
/// place and kept aside, the defaults are used; the keyboard drives the menu to the
/// settings page, a change is written to the settings file, and Quit (a row to reach and
/// choose, never one key) ends the program cleanly.
/// The editor as a designer uses it: a click in the view selects, Delete deletes, Ctrl+S
/// saves (the title's dirty marker comes and goes), Ctrl+Z brings the entity back and the
/// level saves as the file it was; a screenshot shows the view and the panels.
#[test]
fn the_editor_selects_deletes_saves_and_undoes_with_mouse_and_keys() {
    let Some((_xvfb, display, dir)) = x_display("editor") else {
        return;
    };
    let levels = dir.join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    let original = std::fs::read_to_string(common::repo().join("levels/first-light.ron"))
        .unwrap()
        .replace(
            "\"../assets/",
            &format!("\"{}/assets/", common::repo().display()),
        );
    let level = levels.join("first-light.ron");
    std::fs::write(&level, &original).unwrap();
    let mut editor = Reaped(
        windowed(&display, &dir)
            .arg("edit")
            .arg(&level)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start gloam edit"),
    );
    let lines = lines_of(editor.0.stdout.take().unwrap());
    // What the editor logs, in the test's output should a step fail.
    let logged = editor.0.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(logged).lines().map_while(Result::ok) {
            println!("editor (stderr): {line}");
        }
    });
    let next_line = |what: &str| {
        let line = lines
            .recv_timeout(Duration::from_secs(30))
            .unwrap_or_else(|_| panic!("no line saying {what}"));
        // What the editor said, in the test's output should a later step fail.
        println!("editor: {line}");
        line
    };
    let id = gloam_window(&display, &mut editor.0);
    let xdotool = |args: &[&str]| xdotool_on(&display, args);
    let key = |key: &str| {
        focus_window(&display, &id);
        xdotool(&["key", key]);
    };
    // The title follows the frame that ran the command, a moment after its line.
    let title_of_becomes = |window: &str, expected: &str| {
        let title = || xdotool(&["getwindowname", window]);
        for _ in 0..40 {
            if title() == expected {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        assert_eq!(title(), expected);
    };
    let title_becomes = |expected: &str| title_of_becomes(&id, expected);
    title_becomes("first-light.ron - Gloam editor");
    // The first frames: the window's interface settles, then a click in the middle of the
    // view picks what is there (the level's overview looks down on the hall).
    std::thread::sleep(Duration::from_secs(2));
    focus_window(&display, &id);
    xdotool(&["mousemove", "--window", &id, "610", "420"]);
    std::thread::sleep(Duration::from_millis(500));
    xdotool(&["click", "1"]);
    let selected = next_line("what the click selected");
    let name = selected
        .strip_prefix("selected ")
        .unwrap_or_else(|| panic!("{selected}"))
        .to_owned();
    let entry = format!("name: \"{name}\"");
    assert!(original.contains(&entry), "{name}");

    key("Delete");
    assert_eq!(next_line("the delete"), "deleted 1");
    title_becomes("*first-light.ron - Gloam editor");
    key("ctrl+s");
    assert_eq!(next_line("the save"), format!("saved {}", level.display()));
    let saved = std::fs::read_to_string(&level).unwrap();
    assert!(!saved.contains(&entry), "{name} is gone from the file");
    assert_eq!(
        std::fs::read_to_string(levels.join("first-light.ron.bak")).unwrap(),
        original
    );
    title_becomes("first-light.ron - Gloam editor");

    key("ctrl+z");
    assert_eq!(next_line("the undo"), "undone");
    key("ctrl+s");
    next_line("the second save");
    assert_eq!(
        std::fs::read_to_string(&level).unwrap(),
        original,
        "back, byte for byte"
    );

    // The screenshot: the panels' dark grey and the lit level in the view.
    let shot = dir.join("editor.png");
    xdotool(&["mousemove", "--window", &id, "5", "5"]);
    std::thread::sleep(Duration::from_secs(1));
    let lit = pixels_in_shot(&display, &id, &shot, (300..900, 200..600), |c| {
        c.iter().any(|&c| c > 90)
    });
    assert!(
        lit > 2000,
        "the view shows the lit level ({lit} bright pixels)"
    );

    // Hot reload: a change on disk by someone else is loaded; a broken file leaves the
    // level as it is and says where the problem is, until it is fixed.
    let brighter = original.replacen("intensity: ", "intensity: 6", 1);
    assert_ne!(brighter, original, "first-light has a lamp to brighten");
    std::fs::write(&level, &brighter).unwrap();
    assert_eq!(
        next_line("the reload"),
        format!("{}: reloaded (changed on disk)", level.display())
    );
    let broken = brighter.replacen("    version: 1,", "    version: 1,\n    bogus: 3,", 1);
    std::fs::write(&level, broken).unwrap();
    let problem = next_line("the broken file's problem");
    assert!(
        problem.starts_with(&format!("{}:4:5: ", level.display())),
        "{problem}"
    );
    std::fs::write(&level, &brighter).unwrap();
    assert_eq!(
        next_line("the fixed file"),
        format!("{}: the file holds the level shown", level.display())
    );

    // Play-test (F5) the level as edited, with an edit not saved: the game's window opens,
    // Esc comes back to the editor, and the edit is still there, unsaved.
    focus_window(&display, &id);
    xdotool(&["mousemove", "--window", &id, "610", "420"]);
    std::thread::sleep(Duration::from_millis(300));
    xdotool(&["click", "1"]);
    let second = next_line("the second selection");
    let second = format!("name: \"{}\"", second.trim_start_matches("selected "));
    key("Delete");
    assert_eq!(next_line("the delete"), "deleted 1");
    key("F5");
    let started = next_line("the play-test");
    assert!(started.starts_with("play-test "), "{started}");
    std::thread::sleep(Duration::from_secs(2));
    let game = gloam_window(&display, &mut editor.0);
    assert!(xdotool(&["getwindowname", &game]).starts_with("Gloam - "));
    focus_window(&display, &game);
    xdotool(&["key", "Escape"]);
    assert_eq!(next_line("the way back"), "play-test left");
    std::thread::sleep(Duration::from_secs(2));
    let back = gloam_window(&display, &mut editor.0);
    assert_eq!(
        xdotool(&["getwindowname", &back]),
        "*first-light.ron - Gloam editor",
        "the edit is still there, unsaved"
    );

    // The exposure map (X): computed off the view's thread, its route reported.
    focus_window(&display, &back);
    xdotool(&["mousemove", "--window", &back, "610", "420"]);
    xdotool(&["key", "x"]);
    let map = next_line("the exposure map");
    assert!(
        map.starts_with("exposure map at 0 s: darkest route peaks at "),
        "{map}"
    );

    let key_back = |key: &str| {
        focus_window(&display, &back);
        xdotool(&["key", key]);
    };
    // Someone else saves the level while the edit is unsaved: the editor asks, and Enter
    // takes the answer that has the keyboard, keeping the edits; the next save replaces
    // their file, which .bak then holds.
    let theirs = original.replacen("intensity: ", "intensity: 4", 1);
    assert_ne!(theirs, original);
    std::fs::write(&level, &theirs).unwrap();
    assert_eq!(
        next_line("the conflict"),
        format!(
            "{} changed on disk while there are unsaved edits",
            level.display()
        )
    );
    std::thread::sleep(Duration::from_millis(500));
    key_back("Return");
    assert_eq!(
        next_line("the answer"),
        "kept the edits; saving will replace the file on disk"
    );
    key_back("ctrl+s");
    assert_eq!(
        next_line("the save over their file"),
        format!("saved {}", level.display())
    );
    let saved = std::fs::read_to_string(&level).unwrap();
    assert!(
        !saved.contains(&second),
        "the edit was kept: {second} is gone"
    );
    assert_eq!(
        std::fs::read_to_string(levels.join("first-light.ron.bak")).unwrap(),
        theirs,
        "their version is kept as .bak"
    );

    // File > Open through the path field (always there, dialog or not): the menu stays
    // open while the field is clicked and typed in.
    let other = levels.join("other.ron");
    std::fs::write(&other, &original).unwrap();
    xdotool(&["mousemove", "--window", &back, "19", "11"]);
    std::thread::sleep(Duration::from_millis(300));
    xdotool(&["click", "1"]);
    std::thread::sleep(Duration::from_millis(500));
    xdotool(&["mousemove", "--window", &back, "150", "84"]);
    std::thread::sleep(Duration::from_millis(300));
    xdotool(&["click", "1"]);
    std::thread::sleep(Duration::from_millis(300));
    key_back("ctrl+a");
    xdotool(&["type", "--delay", "20", &other.display().to_string()]);
    xdotool(&["mousemove", "--window", &back, "55", "106"]);
    std::thread::sleep(Duration::from_millis(300));
    xdotool(&["click", "1"]);
    assert_eq!(next_line("the open"), format!("opened {}", other.display()));
    title_of_becomes(&back, "other.ron - Gloam editor");
    println!("screenshot: {}", shot.display());
}

/// A designer's day in the window, by mouse and keys: `gloam edit --new`, the palette's
/// path-traced thumbnails, a warden and a shard placed from it, the play-check (F6) proving
/// the level can be finished unseen, the exposure map (X), and the first save writing the
/// new file, which loads.
#[test]
fn a_new_level_is_built_from_the_palette_play_checked_and_saved_in_the_window() {
    let Some((_xvfb, display, dir)) = x_display("editor-day") else {
        return;
    };
    let levels = dir.join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    std::os::unix::fs::symlink(common::repo().join("assets"), dir.join("assets")).unwrap();
    let level = levels.join("vault.ron");
    let mut editor = Reaped(
        windowed(&display, &dir)
            .arg("edit")
            .arg("--new")
            .arg(&level)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start gloam edit --new"),
    );
    let lines = lines_of(editor.0.stdout.take().unwrap());
    let line_within = |what: &str, seconds: u64| {
        let line = lines
            .recv_timeout(Duration::from_secs(seconds))
            .unwrap_or_else(|_| panic!("no line saying {what}"));
        println!("editor: {line}");
        line
    };
    let id = gloam_window(&display, &mut editor.0);
    let xdotool = |args: &[&str]| xdotool_on(&display, args);
    let click = |x: u32, y: u32| {
        focus_window(&display, &id);
        xdotool(&["mousemove", "--window", &id, &x.to_string(), &y.to_string()]);
        std::thread::sleep(Duration::from_millis(300));
        xdotool(&["click", "1"]);
        std::thread::sleep(Duration::from_millis(300));
    };
    let key = |key: &str| {
        focus_window(&display, &id);
        xdotool(&["key", key]);
    };
    std::thread::sleep(Duration::from_secs(2));
    // The palette's warden tile, then the floor by the east wall, in the template's
    // overview; then the shard's tile and the dark north-west corner.
    click(163, 514);
    click(690, 420);
    assert_eq!(line_within("the warden placed", 30), "placed warden");
    click(99, 514);
    click(548, 332);
    assert_eq!(line_within("the shard placed", 30), "placed shard");

    key("F6");
    let started = line_within("the play-check starting", 30);
    assert!(
        started.starts_with("play-check: the bot is playing"),
        "{started}"
    );
    let proven = line_within("the play-check's answer", 180);
    assert!(proven.starts_with("play-check: won unseen in "), "{proven}");
    assert!(proven.contains("1 of 1 shards"), "{proven}");

    key("x");
    let map = line_within("the exposure map", 60);
    assert!(map.starts_with("exposure map at 0 s: "), "{map}");

    key("ctrl+s");
    assert_eq!(
        line_within("the save", 30),
        format!("saved {}", level.display())
    );
    let saved = Scene::load(&level).expect("the new level loads");
    let has = |name: &str| saved.level.entities.iter().any(|e| e.name == name);
    assert!(has("warden") && has("shard") && has("way out"));

    // The palette shows the thumbnails the path tracer made (each tile's studio sky is
    // near white, which nothing else in the panels is), and they are in the cache.
    xdotool(&["mousemove", "--window", &id, "5", "5"]);
    std::thread::sleep(Duration::from_secs(1));
    let shot = dir.join("editor-day.png");
    let sky = pixels_in_shot(&display, &id, &shot, (0..210, 480..740), |c| {
        c.iter().all(|&c| c > 200)
    });
    assert!(sky > 5000, "thumbnails in the palette ({sky} sky pixels)");
    let cached = std::fs::read_dir(dir.join("cache/thumbnails")).map_or(0, |files| files.count());
    assert!(cached > 0, "the thumbnails are kept");
    println!("screenshot: {}", shot.display());
}

#[test]
fn the_main_menu_names_a_broken_settings_file_saves_a_change_and_quits_from_its_row() {
    let Some((_xvfb, display, dir)) = x_display("menu") else {
        return;
    };
    let config = dir.join("config");
    std::fs::create_dir_all(&config).unwrap();
    let settings = config.join("settings.ron");
    std::fs::write(
        &settings,
        "(\n    field_of_view: 70.0,\n    brightnes: 2.0,\n)\n",
    )
    .unwrap();
    // The pointer rests where the menu's second row appears (its window opens at the
    // display's corner, 320 x 180, laid out in 426 x 240 points; the row spans 124 to 150
    // points down): a window opening under a still pointer is no move, so the keyboard's
    // choice below still starts at the first row.
    let pointer = Command::new("xdotool")
        .args(["mousemove", "100", "103"])
        .env("DISPLAY", &display)
        .status()
        .unwrap();
    assert!(pointer.success(), "xdotool mousemove");
    let mut menu = Reaped(
        windowed(&display, &dir)
            .args(["play", "--width", "160", "--height", "90"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start gloam"),
    );
    let stderr = lines_of(menu.0.stderr.take().unwrap());
    // Its own lines start with `gloam:`; what winit logs about the X server may come first.
    let warning = std::iter::from_fn(|| stderr.recv_timeout(Duration::from_secs(60)).ok())
        .find(|line| line.starts_with("gloam:"))
        .expect("a line about the settings file");
    assert!(
        warning.starts_with(&format!("gloam: {}:3:", settings.display())),
        "{warning}"
    );
    assert!(warning.contains("brightnes"), "{warning}");
    assert!(!settings.exists(), "the broken file is moved aside");
    assert!(config.join("settings.ron.broken").exists());

    let id = gloam_window(&display, &mut menu.0);
    // Real key presses (XTEST) to the focused window: winit ignores synthetic events.
    let xdotool = |args: &[&str]| {
        xdotool_on(&display, args);
    };
    let keys = |keys: &[&str]| {
        for key in keys {
            focus_window(&display, &id);
            xdotool(&["key", key]);
            std::thread::sleep(Duration::from_millis(300));
        }
    };
    // Main menu: Play, Choose a level, Settings, Quit. Settings' first row is the mouse
    // sensitivity; Right steps it up and saves.
    keys(&["Down", "Down", "Return", "Right"]);
    let mut saved = String::new();
    for _ in 0..100 {
        saved = std::fs::read_to_string(&settings).unwrap_or_default();
        if saved.contains("mouse_sensitivity") {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let written: gloam::app::settings::Settings =
        ron::from_str(&saved).unwrap_or_else(|error| panic!("{error}: {saved}"));
    assert!((written.mouse_sensitivity - 1.1).abs() < 1e-4, "{saved}");
    assert_eq!(
        written.brightness, 1.0,
        "the defaults replaced the broken file"
    );
    // Esc back to the main menu (Settings still chosen), Down to Quit, Enter chooses it.
    keys(&["Escape", "Down", "Return"]);
    let mut exited = None;
    for _ in 0..100 {
        if let Ok(Some(status)) = menu.0.try_wait() {
            exited = Some(status);
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(exited.is_some_and(|s| s.success()), "{exited:?}");
}

/// Losing the focus pauses an attempt: while another window has the keys the level waits
/// under the pause menu (the recording gains no steps), and the menu is there when the
/// player comes back (its fifth row quits).
#[test]
fn losing_the_focus_pauses_the_attempt() {
    let Some((_xvfb, display, dir)) = x_display("focus") else {
        return;
    };
    let record = dir.join("attempt.json");
    let started = std::time::Instant::now();
    let mut game = Reaped(
        windowed(&display, &dir)
            .args([
                "play",
                "levels/first-light.ron",
                "--width",
                "160",
                "--height",
                "90",
            ])
            .arg("--record")
            .arg(&record)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start gloam play"),
    );
    let id = gloam_window(&display, &mut game.0);
    let xdotool = |args: &[&str]| xdotool_on(&display, args);
    focus_window(&display, &id);
    std::thread::sleep(Duration::from_secs(2));
    // The keys go to the root window: no window manager here, so nothing else to give them.
    let root = xdotool(&["search", "--maxdepth", "0", ""]);
    let playing = started.elapsed().as_secs_f64();
    xdotool(&["windowfocus", "--sync", &root]);
    std::thread::sleep(Duration::from_secs(6));
    // Back in the window: Resume, Restart, Settings, Main menu, Quit.
    for key in ["Down", "Down", "Down", "Down", "Return"] {
        focus_window(&display, &id);
        xdotool(&["key", key]);
        std::thread::sleep(Duration::from_millis(300));
    }
    let mut exited = None;
    for _ in 0..100 {
        if let Ok(Some(status)) = game.0.try_wait() {
            exited = Some(status);
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(
        exited.is_some_and(|s| s.success()),
        "the pause menu's Quit did not end the game: {exited:?}"
    );
    let (recording, _) = gloam::headless::replay::read_recording(&record).unwrap();
    let seconds = recording.steps.len() as f64 / 60.0;
    assert!(
        seconds < playing + 1.0,
        "{seconds:.1} s of play recorded, {playing:.1} s before the focus left and 6 s after"
    );
}

trait WaitOutput {
    fn wait_with_output_or_stderr(&mut self) -> String;
}

impl WaitOutput for Child {
    fn wait_with_output_or_stderr(&mut self) -> String {
        let _ = self.wait();
        let mut text = String::new();
        if let Some(stderr) = self.stderr.as_mut() {
            let _ = std::io::Read::read_to_string(stderr, &mut text);
        }
        text
    }
}
