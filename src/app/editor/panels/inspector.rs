//! The editor's inspector panel: the selected entity's fields, edited in place (transform,
//! instance and its material overrides, light, warden, shard, exit, camera, knock, mover).

use super::*;

impl Panels {
    pub(super) fn inspector(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        out: &mut Vec<Command>,
    ) {
        ui.heading("Inspector");
        let selected: Vec<&EntityDef> = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .collect();
        match selected.as_slice() {
            [] => {
                ui.weak("Nothing selected: the level's own properties.");
                let mut properties = frame.properties.clone();
                level_properties(ui, &mut properties, &self.sounds);
                if properties != frame.properties {
                    out.push(Command::Properties(Box::new(properties)));
                }
            }
            [original] => {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    let mut def = (*original).clone();
                    let choices = Choices {
                        materials: &frame.materials,
                        clips: &frame.clips,
                        assets: &self.asset_names,
                        sounds: &self.sounds,
                    };
                    inspect(ui, &mut def, &choices);
                    let taken = def.name != original.name
                        && frame.defs.iter().any(|(_, other)| other.name == def.name);
                    if taken || def.name.trim().is_empty() {
                        ui.colored_label(
                            Color32::LIGHT_RED,
                            "names must be unique and not empty: kept the old one",
                        );
                        def.name = original.name.clone();
                    }
                    if def != **original {
                        out.push(Command::Edit {
                            name: original.name.clone(),
                            def: Box::new(def),
                        });
                    }
                });
            }
            many => {
                ui.label(format!("{} selected", many.len()));
                for def in many {
                    ui.label(&def.name);
                }
            }
        }
    }
}

/// The level's name, campaign place, sky and ambience (chosen among the `sounds` that
/// exist, so a level never names a missing file).
fn level_properties(ui: &mut egui::Ui, properties: &mut LevelProperties, sounds: &[String]) {
    ui.horizontal(|ui| {
        ui.label("Name");
        ui.text_edit_singleline(&mut properties.name);
    });
    ui.horizontal(|ui| {
        let mut in_campaign = properties.campaign.is_some();
        ui.checkbox(&mut in_campaign, "Campaign level");
        match (in_campaign, &mut properties.campaign) {
            (true, Some(place)) => {
                ui.add(egui::DragValue::new(place).range(1..=999).prefix("no. "));
            }
            (true, campaign @ None) => *campaign = Some(1),
            (false, campaign) => *campaign = None,
        }
    });
    let sky = &mut properties.environment.sky;
    vec3_row(ui, "Sky", sky, 0.001, "");
    *sky = sky.max(Vec3::ZERO);
    ui.weak("the sky's radiance (linear RGB, W/(sr m²))");
    let ambience = &mut properties.environment.ambience;
    ui.horizontal(|ui| {
        ui.label("Ambience");
        let shown = ambience
            .as_ref()
            .map_or("none".to_owned(), |ambience| ambience.asset.clone());
        egui::ComboBox::from_id_salt("ambience")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                if ui.selectable_label(ambience.is_none(), "none").clicked() {
                    *ambience = None;
                }
                for sound in sounds {
                    let chosen = ambience.as_ref().is_some_and(|a| a.asset == *sound);
                    if ui.selectable_label(chosen, sound).clicked() {
                        let gain_db = ambience.as_ref().map_or(0.0, |a| a.gain_db);
                        *ambience = Some(AmbienceDef {
                            asset: sound.clone(),
                            gain_db,
                        });
                    }
                }
            });
    });
    if let Some(ambience) = ambience {
        ui.horizontal(|ui| {
            ui.label("Gain");
            ui.add(
                egui::DragValue::new(&mut ambience.gain_db)
                    .range(-60.0..=12.0)
                    .speed(0.1)
                    .suffix(" dB"),
            );
        });
    }
}

/// A rotation as the level writes it: degrees about X, Y and Z, applied Y, X, Z
/// (`TransformDef::rotation_quat`'s inverse), rounded to a thousandth of a degree so a
/// round trip through the quaternion does not leave 89.99999 in the file.
pub(super) fn euler_degrees(rotation: Quat) -> Vec3 {
    let (y, x, z) = rotation.to_euler(EulerRot::YXZ);
    let round = |radians: f32| {
        let degrees = (radians.to_degrees() * 1000.0).round() / 1000.0;
        if degrees == 0.0 { 0.0 } else { degrees }
    };
    Vec3::new(round(x), round(y), round(z))
}

/// What an entity's fields may be set to: its asset's materials and clips, and the
/// project's assets and sounds as the level names them.
struct Choices<'a> {
    materials: &'a [Material],
    clips: &'a [String],
    assets: &'a [String],
    sounds: &'a [String],
}

/// One of `choices` for `value`, in a drop-down (`value` shown as it is, chosen or not).
fn choose(ui: &mut egui::Ui, salt: &str, value: &mut String, choices: &[String]) {
    egui::ComboBox::from_id_salt(salt)
        .selected_text(value.as_str())
        .show_ui(ui, |ui| {
            for choice in choices {
                if ui.selectable_label(choice == value, choice).clicked() {
                    value.clone_from(choice);
                }
            }
        });
}

/// The inspector's fields for one entity: every component it has, and a box to add each
/// one it has not.
fn inspect(ui: &mut egui::Ui, def: &mut EntityDef, choices: &Choices) {
    let materials = choices.materials;
    ui.horizontal(|ui| {
        ui.label("Name");
        ui.text_edit_singleline(&mut def.name);
    });
    egui::CollapsingHeader::new("Transform")
        .default_open(true)
        .show(ui, |ui| {
            vec3_row(ui, "Position", &mut def.transform.translation, 0.01, " m");
            vec3_row(ui, "Rotation", &mut def.transform.rotation, 0.5, "°");
            vec3_row(ui, "Scale", &mut def.transform.scale, 0.01, "");
            let scale = &mut def.transform.scale;
            *scale = scale.max(Vec3::splat(0.001));
        });
    if let Some(instance) = &mut def.instance {
        egui::CollapsingHeader::new("Asset")
            .default_open(true)
            .show(ui, |ui| {
                // A swap keeps the overrides and the clip the new asset has too (the window
                // fits them: `edit::fit_to_asset`).
                choose(ui, "instance asset", &mut instance.asset, choices.assets);
                material_overrides(ui, &mut instance.material_overrides, materials);
            });
        if let Some(first) = choices.clips.first() {
            component(
                ui,
                "Animation",
                &mut def.animation,
                || AnimationDef {
                    clip: first.clone(),
                    playback: Playback::Loop,
                    speed: 1.0,
                    start: 0.0,
                },
                |ui, animation| {
                    ui.horizontal(|ui| {
                        ui.label("clip");
                        choose(ui, "animation clip", &mut animation.clip, choices.clips);
                    });
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut animation.playback, Playback::Loop, "loop");
                        ui.radio_value(&mut animation.playback, Playback::Once, "once");
                    });
                    number(ui, "speed", &mut animation.speed, 0.01, -10.0..=10.0, "x");
                    number(ui, "start", &mut animation.start, 0.01, 0.0..=3600.0, " s");
                },
            );
        } else if def.animation.is_some() {
            ui.colored_label(Color32::LIGHT_RED, "the asset has no animation clips");
        }
        component(
            ui,
            "Deformer",
            &mut def.deformer,
            || DeformerDef::Wobble {
                amplitude: 0.05,
                period: 2.0,
            },
            |ui, deformer| {
                let wave = matches!(deformer, DeformerDef::Wave { .. });
                let mut chosen = wave;
                ui.horizontal(|ui| {
                    ui.radio_value(&mut chosen, false, "wobble");
                    ui.radio_value(&mut chosen, true, "wave");
                });
                if chosen != wave {
                    let (amplitude, period) = match *deformer {
                        DeformerDef::Wave {
                            amplitude, period, ..
                        }
                        | DeformerDef::Wobble { amplitude, period } => (amplitude, period),
                    };
                    *deformer = if chosen {
                        DeformerDef::Wave {
                            amplitude,
                            wavelength: 1.0,
                            period,
                            direction: Vec3::X,
                        }
                    } else {
                        DeformerDef::Wobble { amplitude, period }
                    };
                }
                match deformer {
                    DeformerDef::Wave {
                        amplitude,
                        wavelength,
                        period,
                        direction,
                    } => {
                        number(ui, "amplitude", amplitude, 0.001, 0.0..=10.0, " m");
                        number(ui, "wavelength", wavelength, 0.01, 0.01..=100.0, " m");
                        number(ui, "period", period, 0.01, 0.01..=100.0, " s");
                        vec3_row(ui, "direction", direction, 0.01, "");
                        if direction.length_squared() == 0.0 {
                            *direction = Vec3::X;
                        }
                    }
                    DeformerDef::Wobble { amplitude, period } => {
                        number(ui, "amplitude", amplitude, 0.001, 0.0..=10.0, " m");
                        number(ui, "period", period, 0.01, 0.01..=100.0, " s");
                    }
                }
            },
        );
    }
    if let Some(first) = choices.sounds.first() {
        component(
            ui,
            "Sound",
            &mut def.sound,
            || SoundDef {
                asset: first.clone(),
                gain_db: 0.0,
                looping: true,
            },
            |ui, sound| {
                choose(ui, "sound asset", &mut sound.asset, choices.sounds);
                number(
                    ui,
                    "gain at 1 m",
                    &mut sound.gain_db,
                    0.1,
                    -60.0..=24.0,
                    " dB",
                );
                ui.checkbox(
                    &mut sound.looping,
                    "loops (else plays once as the level starts)",
                );
            },
        );
    }
    component(
        ui,
        "Light",
        &mut def.light,
        || LightDef::Point {
            color: Vec3::ONE,
            intensity: 10.0,
        },
        |ui, light| {
            let (color, intensity) = match light {
                LightDef::Point { color, intensity }
                | LightDef::Directional { color, intensity }
                | LightDef::Spot {
                    color, intensity, ..
                } => (color, intensity),
            };
            let mut rgb = color.to_array();
            ui.horizontal(|ui| {
                ui.label("colour");
                ui.color_edit_button_rgb(&mut rgb);
            });
            *color = Vec3::from_array(rgb);
            number(ui, "intensity", intensity, 0.1, 0.0..=10_000.0, "");
            if let LightDef::Spot {
                inner_cone_degrees,
                outer_cone_degrees,
                ..
            } = light
            {
                number(ui, "inner cone", inner_cone_degrees, 0.5, 0.0..=90.0, "°");
                number(ui, "outer cone", outer_cone_degrees, 0.5, 0.0..=90.0, "°");
                *inner_cone_degrees = inner_cone_degrees.min(*outer_cone_degrees);
            }
            let kind = match light {
                LightDef::Point { .. } => 0,
                LightDef::Spot { .. } => 1,
                LightDef::Directional { .. } => 2,
            };
            let mut chosen = kind;
            ui.horizontal(|ui| {
                ui.radio_value(&mut chosen, 0, "point");
                ui.radio_value(&mut chosen, 1, "spot");
                ui.radio_value(&mut chosen, 2, "directional");
            });
            if chosen != kind {
                let (color, intensity) = match *light {
                    LightDef::Point { color, intensity }
                    | LightDef::Directional { color, intensity }
                    | LightDef::Spot {
                        color, intensity, ..
                    } => (color, intensity),
                };
                *light = match chosen {
                    0 => LightDef::Point { color, intensity },
                    1 => LightDef::Spot {
                        color,
                        intensity,
                        inner_cone_degrees: 25.0,
                        outer_cone_degrees: 38.0,
                    },
                    _ => LightDef::Directional { color, intensity },
                };
            }
        },
    );
    component(
        ui,
        "Warden",
        &mut def.warden,
        || WardenDef::walking(Vec::new()),
        |ui, warden| {
            number(ui, "speed", &mut warden.speed, 0.05, 0.1..=10.0, " m/s");
            ui.label("route (drag the squares in the view)");
            let mut remove = None;
            for (index, point) in warden.route.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!("{}", index + 1));
                    for value in [&mut point.x, &mut point.y, &mut point.z] {
                        ui.add(egui::DragValue::new(value).speed(0.05));
                    }
                    if ui.small_button("x").clicked() {
                        remove = Some(index);
                    }
                });
            }
            if let Some(index) = remove {
                warden.route.remove(index);
            }
            if ui.button("add a waypoint").clicked() {
                let last = warden.route.last().copied().unwrap_or_default();
                warden.route.push(last + Vec3::new(1.0, 0.0, 0.0));
            }
            ui.label("lamp");
            let lamp = &mut warden.lamp;
            let mut rgb = lamp.color.to_array();
            ui.horizontal(|ui| {
                ui.label("colour");
                ui.color_edit_button_rgb(&mut rgb);
            });
            lamp.color = Vec3::from_array(rgb);
            number(
                ui,
                "intensity",
                &mut lamp.intensity,
                0.1,
                0.0..=10_000.0,
                "",
            );
            number(
                ui,
                "inner cone",
                &mut lamp.inner_cone_degrees,
                0.5,
                0.0..=90.0,
                "°",
            );
            number(
                ui,
                "outer cone",
                &mut lamp.outer_cone_degrees,
                0.5,
                0.0..=90.0,
                "°",
            );
            number(ui, "tilt", &mut lamp.tilt_degrees, 0.5, -90.0..=90.0, "°");
            number(ui, "height", &mut lamp.height, 0.01, 0.0..=5.0, " m");
        },
    );
    component(
        ui,
        "Shard",
        &mut def.shard,
        ShardDef::default,
        |ui, shard| {
            number(
                ui,
                "pickup radius",
                &mut shard.radius,
                0.01,
                0.05..=5.0,
                " m",
            );
        },
    );
    component(ui, "Exit", &mut def.exit, ExitDef::default, |ui, exit| {
        number(ui, "radius", &mut exit.radius, 0.01, 0.1..=10.0, " m");
    });
    component(
        ui,
        "Player start",
        &mut def.player_spawn,
        PlayerSpawn::default,
        |ui, spawn| {
            number(
                ui,
                "eye height",
                &mut spawn.eye_height,
                0.01,
                0.5..=2.5,
                " m",
            );
        },
    );
    component(
        ui,
        "Camera",
        &mut def.camera,
        || CameraDef {
            yfov_degrees: 60.0,
            znear: 0.05,
        },
        |ui, camera| {
            number(
                ui,
                "field of view",
                &mut camera.yfov_degrees,
                0.5,
                10.0..=150.0,
                "°",
            );
        },
    );
    component(
        ui,
        "Knocks over",
        &mut def.knock,
        KnockDef::default,
        |ui, knock| {
            number(ui, "radius", &mut knock.radius, 0.01, 0.05..=3.0, " m");
            number(ui, "noise reach", &mut knock.noise, 0.1, 0.0..=50.0, " m");
        },
    );
    component(
        ui,
        "Mover",
        &mut def.mover,
        || MoverDef {
            offset: Vec3::new(1.0, 0.0, 0.0),
            period: 4.0,
        },
        |ui, mover| {
            vec3_row(ui, "offset", &mut mover.offset, 0.01, " m");
            number(ui, "period", &mut mover.period, 0.05, 0.1..=120.0, " s");
        },
    );
}

/// A component's section: a box that adds or removes it, and its fields while present.
/// Each of the asset's materials, with a box per value the level may replace for this
/// instance; ticking one starts from the asset's value, and an override with no value
/// left is dropped, so the level file names only what differs.
fn material_overrides(
    ui: &mut egui::Ui,
    overrides: &mut BTreeMap<String, MaterialOverride>,
    materials: &[Material],
) {
    let mut shown = Vec::new();
    for material in materials {
        // Overrides are keyed by name: an unnamed material cannot be named by one, and a
        // name the asset repeats names all its materials at once.
        if material.name.is_empty() || shown.contains(&&material.name) {
            continue;
        }
        shown.push(&material.name);
        let mut change = overrides.get(&material.name).cloned().unwrap_or_default();
        let changed = if change == MaterialOverride::default() {
            ""
        } else {
            " (changed)"
        };
        egui::CollapsingHeader::new(format!("material '{}'{changed}", material.name))
            .id_salt(&material.name)
            .show(ui, |ui| material_fields(ui, &mut change, material));
        if change == MaterialOverride::default() {
            overrides.remove(&material.name);
        } else {
            overrides.insert(material.name.clone(), change);
        }
    }
    if shown.len() < materials.len() {
        ui.weak("(unnamed materials cannot be overridden)");
    }
}

fn material_fields(ui: &mut egui::Ui, change: &mut MaterialOverride, asset: &Material) {
    overridable(
        ui,
        "base colour",
        &mut change.base_color,
        asset.base_color,
        |ui, colour| {
            let mut rgb = colour.truncate().to_array();
            ui.color_edit_button_rgb(&mut rgb);
            *colour = Vec3::from_array(rgb).extend(colour.w);
        },
    );
    let unit = |ui: &mut egui::Ui, value: &mut f32| {
        ui.add(egui::Slider::new(value, 0.0..=1.0));
    };
    overridable(ui, "metallic", &mut change.metallic, asset.metallic, unit);
    overridable(
        ui,
        "roughness",
        &mut change.roughness,
        asset.roughness,
        unit,
    );
    overridable(
        ui,
        "transmission",
        &mut change.transmission,
        asset.transmission,
        unit,
    );
    overridable(ui, "ior", &mut change.ior, asset.ior, |ui, ior| {
        ui.add(egui::DragValue::new(ior).speed(0.01).range(1.0..=3.0));
    });
    overridable(
        ui,
        "emissive",
        &mut change.emissive,
        asset.emissive,
        |ui, radiance| {
            for channel in [&mut radiance.x, &mut radiance.y, &mut radiance.z] {
                ui.add(
                    egui::DragValue::new(channel)
                        .speed(0.05)
                        .range(0.0..=10_000.0),
                );
            }
        },
    );
    overridable(
        ui,
        "double sided",
        &mut change.double_sided,
        asset.double_sided,
        |ui, on| {
            ui.checkbox(on, "");
        },
    );
}

/// One value of a material override: ticked, the level's value (starting from the
/// asset's); not ticked, the asset's.
fn overridable<T>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut Option<T>,
    asset: T,
    edit: impl FnOnce(&mut egui::Ui, &mut T),
) {
    ui.horizontal(|ui| {
        let mut on = value.is_some();
        ui.checkbox(&mut on, label);
        match (on, value.is_some()) {
            (true, false) => *value = Some(asset),
            (false, true) => *value = None,
            _ => {}
        }
        match value {
            Some(value) => edit(ui, value),
            None => {
                ui.weak("as the asset");
            }
        }
    });
}

fn component<T>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut Option<T>,
    make: impl FnOnce() -> T,
    fields: impl FnOnce(&mut egui::Ui, &mut T),
) {
    let mut present = value.is_some();
    ui.separator();
    ui.checkbox(&mut present, label);
    match (present, value.is_some()) {
        (true, false) => *value = Some(make()),
        (false, true) => *value = None,
        _ => {}
    }
    if let Some(inner) = value {
        ui.indent(label, |ui| fields(ui, inner));
    }
}

fn vec3_row(ui: &mut egui::Ui, label: &str, value: &mut Vec3, speed: f64, suffix: &str) {
    ui.horizontal(|ui| {
        ui.label(label);
        for axis in [&mut value.x, &mut value.y, &mut value.z] {
            ui.add(egui::DragValue::new(axis).speed(speed).suffix(suffix));
        }
    });
}

fn number(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut f32,
    speed: f64,
    range: std::ops::RangeInclusive<f32>,
    suffix: &str,
) {
    ui.horizontal(|ui| {
        ui.label(label);
        ui.add(
            egui::DragValue::new(value)
                .speed(speed)
                .range(range)
                .suffix(suffix),
        );
    });
}
