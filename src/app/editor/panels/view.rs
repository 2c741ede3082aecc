//! The editor's central panel: the path-traced view and what is drawn over it (markers,
//! the transform gizmo, wardens' beats, the exposure and audibility maps, the play-check's
//! route), and the picking, dragging and flying the pointer does there.

use super::*;

impl Panels {
    /// The problems of a file on disk that does not load, over the top of the view.
    fn file_error(&self, painter: &egui::Painter, rect: Rect) {
        let Some(error) = &self.file_error else {
            return;
        };
        let text = painter.layout(
            error.clone(),
            egui::FontId::monospace(12.0),
            Color32::from_rgb(255, 120, 110),
            rect.width() - 16.0,
        );
        let at = rect.min + egui::vec2(8.0, 8.0);
        painter.rect_filled(
            Rect::from_min_size(at, text.size()).expand(4.0),
            3.0,
            Color32::from_black_alpha(200),
        );
        painter.galley(at, text, Color32::WHITE);
    }

    /// The path-traced view, its overlays, the gizmo, and what clicks in it do.
    pub(super) fn view(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        view: &ViewState,
        camera: &FlyCamera,
        overlays: Overlays,
        out: &mut Vec<Command>,
    ) {
        let available = ui.available_rect_before_wrap();
        let aspect = view.width as f32 / view.height as f32;
        let mut size = available.size();
        if size.x / size.y.max(1.0) > aspect {
            size.x = size.y * aspect;
        } else {
            size.y = size.x / aspect;
        }
        let rect = Rect::from_center_size(available.center(), size);
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.image(
            view.texture,
            rect,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            Color32::WHITE,
        );
        let (pressed_secondary, secondary_down) = ui.input(|i| {
            (
                i.pointer.button_pressed(egui::PointerButton::Secondary),
                i.pointer.secondary_down(),
            )
        });
        if response.hovered() && pressed_secondary {
            self.flying = true;
        }
        if !secondary_down {
            self.flying = false;
        }

        let projection = ViewProjection::new(camera, view, rect);
        if let Some((checked, stale)) = overlays.play_check {
            play_check_overlay(&painter, checked, stale, &projection);
        }
        if self.exposure.on {
            match (self.exposure.heard, overlays.audibility, overlays.exposure) {
                (Some(_), Some(heard), _) => audibility_overlay(&painter, heard, &projection),
                (None, _, Some(exposure)) => self.exposure_overlay(&painter, exposure, &projection),
                _ => {}
            }
            self.exposure_controls(ui, rect);
        }
        if self.show_grid {
            ground_grid(
                &painter,
                &projection,
                camera.position,
                self.grid,
                overlays.depth,
            );
        }
        self.overlays(&painter, frame, &projection);
        self.measure_overlay(&painter, &projection);
        self.file_error(&painter, rect);
        let gizmo_busy = self.gizmo(ui, frame, camera, rect, out);
        let waypoint_busy = self.waypoints(ui, &response, frame, &projection, camera, view, out);
        self.box_select(
            ui,
            &response,
            frame,
            &projection,
            gizmo_busy || waypoint_busy,
            out,
        );
        // A click is the view's when it lands on the view's rectangle with no window or
        // popup over it and no handle under it (the busy flags). Not `response.clicked()`:
        // the gizmo senses clicks through a widget of its own at the pointer, above the
        // view in the same layer, which takes the click after a placement (the new
        // entity's gizmo left under the pointer) though no handle is there.
        let clicked = response.contains_pointer() && ui.input(|i| i.pointer.primary_clicked());
        if clicked
            && !gizmo_busy
            && !waypoint_busy
            && let Some(at) = ui.input(|i| i.pointer.interact_pos())
        {
            let add = ui.input(|i| i.modifiers.shift);
            let fraction = Vec2::new(
                (at.x - rect.min.x) / rect.width(),
                (at.y - rect.min.y) / rect.height(),
            );
            let ray = view_ray(camera, view.width, view.height, fraction);
            if self.measuring {
                if self.measured.len() == 2 {
                    self.measured.clear();
                }
                out.push(Command::Measure(ray));
            } else if let Some(item) = self.armed.clone() {
                let snap = self.snapping.then_some(self.grid);
                out.push(Command::Place { ray, item, snap });
                if !add {
                    self.armed = None;
                }
            } else if let Some(place) = marker_at(frame, &projection, at) {
                out.push(Command::Select { place, add });
            } else {
                out.push(Command::Pick { ray, add });
            }
        }
    }

    /// The exposure map over the floor: each cell the player reaches in its colour (standing
    /// or crouching), the darkest route from the spawn through the shards to the exit, its
    /// lit chokepoints, and the wardens where the time slider has put them.
    fn exposure_overlay(
        &self,
        painter: &egui::Painter,
        exposure: &Exposure,
        projection: &ViewProjection,
    ) {
        let map = &exposure.map;
        let threshold = self.exposure.threshold;
        let mut mesh = egui::Mesh::default();
        for storey in &map.storeys {
            let values = if self.exposure.crouching {
                &storey.crouching
            } else {
                &storey.standing
            };
            for (column, (value, floor)) in values.iter().zip(&storey.floor).enumerate() {
                let (Some(value), Some(floor)) = (value, floor) else {
                    continue;
                };
                let x = map.origin.0 + (column % map.width) as f32 * map.cell_size;
                let z = map.origin.1 + (column / map.width) as f32 * map.cell_size;
                let [r, g, b] = crate::headless::exposure::colour(*value, threshold);
                floor_cell(
                    &mut mesh,
                    projection,
                    Vec3::new(x, *floor, z),
                    map.cell_size,
                    Color32::from_rgba_unmultiplied(r, g, b, 120),
                );
            }
        }
        painter.add(mesh);
        let route: Vec<Pos2> = map
            .route
            .path
            .iter()
            .filter_map(|&p| projection.point(p + Vec3::Y * 0.05))
            .collect();
        painter.add(egui::Shape::line(
            route,
            Stroke::new(2.0_f32, Color32::from_rgb(120, 255, 200)),
        ));
        for &choke in &map.route.chokepoints {
            ring(painter, projection, choke, "lit, no way round", LIT);
        }
        for &(feet, facing) in &exposure.wardens {
            if let (Some(at), Some(ahead)) = (
                projection.point(feet + Vec3::Y * 0.05),
                projection.point(feet + Vec3::Y * 0.05 + facing * 0.8),
            ) {
                painter.circle_filled(at, 6.0, Color32::from_rgb(230, 60, 60));
                painter.line_segment(
                    [at, ahead],
                    Stroke::new(2.0_f32, Color32::from_rgb(230, 60, 60)),
                );
            }
        }
    }

    /// The overlay's controls, in a corner of the view.
    fn exposure_controls(&mut self, ui: &mut egui::Ui, rect: Rect) {
        // In front of the view it lies over.
        egui::Area::new(egui::Id::new("exposure controls"))
            .order(egui::Order::Foreground)
            .fixed_pos(Pos2::new(rect.min.x + 8.0, rect.max.y - 116.0))
            .show(ui.ctx(), |ui| {
                egui::Frame::popup(ui.style()).show(ui, |ui| {
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut self.exposure.heard, None, "seen");
                        for noise in NoiseKind::ALL {
                            ui.radio_value(
                                &mut self.exposure.heard,
                                Some(noise),
                                format!("heard: {}", noise.name()),
                            );
                        }
                    });
                    if self.exposure.heard.is_none() {
                        ui.horizontal(|ui| {
                            ui.radio_value(&mut self.exposure.crouching, false, "standing");
                            ui.radio_value(&mut self.exposure.crouching, true, "crouching");
                        });
                    }
                    ui.add(
                        egui::Slider::new(&mut self.exposure.time, 0.0..=EXPOSURE_TIME_MAX)
                            .step_by(0.25)
                            .text("s into the beats"),
                    );
                    ui.label(&self.exposure.status);
                });
            });
    }

    /// A primary drag that starts on nothing else draws a box; on release, every entity
    /// whose place (its origin, or its marker) lies inside becomes the selection (Shift
    /// adds to it).
    fn box_select(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        frame: &FrameInput,
        projection: &ViewProjection,
        busy: bool,
        out: &mut Vec<Command>,
    ) {
        let pointer = ui.input(|i| i.pointer.interact_pos());
        if response.drag_started_by(egui::PointerButton::Primary)
            && !busy
            && !self.measuring
            && self.armed.is_none()
            && !self.flying
        {
            self.box_from = ui.input(|i| i.pointer.press_origin());
        }
        let (Some(from), Some(to)) = (self.box_from, pointer) else {
            return;
        };
        let area = Rect::from_two_pos(from, to);
        let colour = Color32::from_rgb(255, 170, 40);
        ui.painter()
            .rect_filled(area, 0.0, colour.gamma_multiply(0.08));
        ui.painter().rect_stroke(
            area,
            0.0,
            Stroke::new(1.0_f32, colour),
            egui::StrokeKind::Inside,
        );
        if response.drag_stopped() || !ui.input(|i| i.pointer.primary_down()) {
            self.box_from = None;
            let places: Vec<LevelEntity> = frame
                .defs
                .iter()
                .filter(|(_, def)| {
                    projection
                        .point(def.transform.translation)
                        .is_some_and(|at| area.contains(at))
                })
                .map(|(place, _)| *place)
                .collect();
            let add = ui.input(|i| i.modifiers.shift);
            out.push(Command::SelectMany { places, add });
        }
    }

    /// The measuring tool's points, the line between them and its length (and its run
    /// along each axis).
    fn measure_overlay(&self, painter: &egui::Painter, projection: &ViewProjection) {
        if !self.measuring {
            return;
        }
        let colour = Color32::from_rgb(120, 230, 255);
        let points: Vec<Option<Pos2>> =
            self.measured.iter().map(|&p| projection.point(p)).collect();
        for at in points.iter().flatten() {
            painter.circle_filled(*at, 4.0, colour);
        }
        if let ([a, b], [Some(pa), Some(pb)]) = (self.measured.as_slice(), points.as_slice()) {
            painter.line_segment([*pa, *pb], Stroke::new(2.0_f32, colour));
            let d = *b - *a;
            painter.text(
                Pos2::new((pa.x + pb.x) * 0.5, (pa.y + pb.y) * 0.5 - 10.0),
                egui::Align2::CENTER_BOTTOM,
                format!(
                    "{:.2} m  (x {:+.2}, y {:+.2}, z {:+.2})",
                    d.length(),
                    d.x,
                    d.y,
                    d.z
                ),
                egui::FontId::proportional(13.0),
                colour,
            );
        }
    }

    /// The selection's boxes, a marker for each entity that draws nothing, and each
    /// warden's beat.
    fn overlays(&self, painter: &egui::Painter, frame: &FrameInput, projection: &ViewProjection) {
        let highlight = Color32::from_rgb(255, 170, 40);
        for (min, max) in &frame.bounds {
            draw_box(
                painter,
                projection,
                *min,
                *max,
                Stroke::new(1.5_f32, highlight),
            );
        }
        for (place, def) in &frame.defs {
            let selected = frame.selection.contains(place);
            if let Some(warden) = &def.warden {
                let colour = if selected {
                    highlight
                } else {
                    Color32::from_rgba_unmultiplied(200, 60, 60, 160)
                };
                let beat = beat_points(def, warden);
                for pair in beat.windows(2) {
                    if let (Some(a), Some(b)) =
                        (projection.point(pair[0]), projection.point(pair[1]))
                    {
                        painter.line_segment([a, b], Stroke::new(1.5_f32, colour));
                    }
                }
                for point in &warden.route {
                    if let Some(at) = projection.point(*point) {
                        painter.rect_filled(
                            Rect::from_center_size(at, egui::vec2(7.0, 7.0)),
                            1.0,
                            colour,
                        );
                    }
                }
            }
            if def.instance.is_some() {
                continue;
            }
            let Some(at) = projection.point(def.transform.translation) else {
                continue;
            };
            let (colour, label) = marker_style(def);
            painter.circle_filled(at, 5.0, colour);
            if selected {
                painter.circle_stroke(at, 8.0, Stroke::new(2.0_f32, highlight));
            }
            if selected || projection.rect.contains(at) && label != "light" {
                painter.text(
                    at + egui::vec2(8.0, -8.0),
                    egui::Align2::LEFT_BOTTOM,
                    &def.name,
                    egui::FontId::proportional(12.0),
                    Color32::from_gray(220),
                );
            }
        }
    }

    /// The gizmo on the selection; true while it has the pointer (hovered or dragged).
    fn gizmo(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        camera: &FlyCamera,
        rect: Rect,
        out: &mut Vec<Command>,
    ) -> bool {
        let selected: Vec<&EntityDef> = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .collect();
        // A locked entity stays where it is: no handles while one is selected.
        let locked = frame.selection.iter().any(|p| self.locked.contains(p));
        if selected.is_empty() || self.flying || locked {
            return false;
        }
        let view = camera.world_from_camera().inverse().as_dmat4();
        let projection = perspective(
            camera.yfov as f64,
            (rect.width() / rect.height()) as f64,
            camera.znear as f64,
        );
        let kind = match self.tool {
            Tool::Move => GizmoModeKind::Translate,
            Tool::Rotate => GizmoModeKind::Rotate,
            Tool::Scale => GizmoModeKind::Scale,
        };
        self.gizmo.update_config(GizmoConfig {
            view_matrix: row_matrix(view),
            projection_matrix: row_matrix(projection),
            viewport: rect,
            modes: GizmoMode::all_from_kind(kind),
            orientation: GizmoOrientation::Global,
            snapping: self.snapping,
            snap_angle: self.angle.to_radians(),
            snap_distance: self.grid,
            snap_scale: 0.1,
            ..GizmoConfig::default()
        });
        let targets: Vec<GizmoTransform> = selected
            .iter()
            .map(|def| {
                let t = &def.transform;
                let q = t.rotation_quat();
                GizmoTransform::from_scale_rotation_translation(
                    mint::Vector3::from(t.scale.as_dvec3().to_array()),
                    mint::Quaternion::from([q.x as f64, q.y as f64, q.z as f64, q.w as f64]),
                    mint::Vector3::from(t.translation.as_dvec3().to_array()),
                )
            })
            .collect();
        if let Some((_, moved)) = self.gizmo.interact(ui, &targets) {
            for (def, transform) in selected.iter().zip(moved) {
                let mut changed = (*def).clone();
                let v = |m: mint::Vector3<f64>| Vec3::new(m.x as f32, m.y as f32, m.z as f32);
                changed.transform.translation = v(transform.translation);
                changed.transform.scale = v(transform.scale);
                let r = transform.rotation;
                let rotation =
                    Quat::from_xyzw(r.v.x as f32, r.v.y as f32, r.v.z as f32, r.s as f32);
                changed.transform.rotation = euler_degrees(rotation);
                if changed != **def {
                    out.push(Command::Edit {
                        name: def.name.clone(),
                        def: Box::new(changed),
                    });
                }
            }
        }
        self.gizmo.is_focused()
    }

    /// A selected warden's waypoints, dragged over the horizontal plane they stand on;
    /// true while one is held or under the pointer.
    #[allow(clippy::too_many_arguments)]
    fn waypoints(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        frame: &FrameInput,
        projection: &ViewProjection,
        camera: &FlyCamera,
        view: &ViewState,
        out: &mut Vec<Command>,
    ) -> bool {
        let pointer = ui.input(|i| i.pointer.hover_pos());
        let wardens = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .filter(|d| d.warden.is_some());
        let mut under = None;
        for def in wardens {
            let Some(warden) = &def.warden else { continue };
            for (index, point) in warden.route.iter().enumerate() {
                if let (Some(at), Some(pointer)) = (projection.point(*point), pointer)
                    && at.distance(pointer) < HANDLE_RADIUS
                {
                    under = Some((def.name.clone(), index));
                }
            }
        }
        if response.drag_started() && self.waypoint.is_none() {
            self.waypoint = under.clone();
        }
        if let Some((name, index)) = self.waypoint.clone() {
            if !self.primary_down {
                self.waypoint = None;
            } else if let (Some(pointer), Some(def)) = (
                pointer,
                frame.defs.iter().map(|(_, d)| d).find(|d| d.name == name),
            ) && let Some(warden) = &def.warden
                && let Some(old) = warden.route.get(index)
            {
                let fraction = Vec2::new(
                    (pointer.x - projection.rect.min.x) / projection.rect.width(),
                    (pointer.y - projection.rect.min.y) / projection.rect.height(),
                );
                let ray = view_ray(camera, view.width, view.height, fraction);
                let origin = Vec3::from(ray.origin);
                let direction = Vec3::from(ray.direction);
                if direction.y.abs() > 1e-5 {
                    let t = (old.y - origin.y) / direction.y;
                    if t > 0.0 {
                        let mut at = origin + direction * t;
                        if self.snapping {
                            at.x = (at.x / self.grid).round() * self.grid;
                            at.z = (at.z / self.grid).round() * self.grid;
                        }
                        at.y = old.y;
                        let mut changed = def.clone();
                        if let Some(route) = changed.warden.as_mut().map(|w| &mut w.route) {
                            route[index] = at;
                        }
                        if changed != *def {
                            out.push(Command::Edit {
                                name,
                                def: Box::new(changed),
                            });
                        }
                    }
                }
            }
        }
        self.waypoint.is_some() || under.is_some()
    }
}

/// Red: lit places with no way round, and where the bot was caught.
const LIT: Color32 = Color32::from_rgb(255, 60, 40);

/// A ring on the floor at `at` with a label beside it.
fn ring(
    painter: &egui::Painter,
    projection: &ViewProjection,
    at: Vec3,
    label: &str,
    colour: Color32,
) {
    if let Some(at) = projection.point(at + Vec3::Y * 0.05) {
        painter.circle_stroke(at, 9.0, Stroke::new(2.5_f32, colour));
        painter.text(
            at + egui::vec2(10.0, -10.0),
            egui::Align2::LEFT_BOTTOM,
            label,
            egui::FontId::proportional(12.0),
            colour,
        );
    }
}

/// The last play-check over the floor: the route the bot walked (green when won unseen,
/// orange otherwise), where it was caught, and the lit chokepoints that left it no route;
/// grey, and said so, when the level has been edited since.
fn play_check_overlay(
    painter: &egui::Painter,
    checked: &Checked,
    stale: bool,
    projection: &ViewProjection,
) {
    let grey = Color32::from_gray(150);
    let route_colour = match (stale, checked.proven()) {
        (true, _) => grey,
        (false, true) => Color32::from_rgb(90, 230, 120),
        (false, false) => Color32::from_rgb(255, 170, 40),
    };
    // A point every tenth of a second: the line looks the same and projects a sixth of
    // the points.
    let route: Vec<Pos2> = checked
        .route
        .iter()
        .step_by(6)
        .chain(checked.route.last())
        .filter_map(|&p| projection.point(p + Vec3::Y * 0.05))
        .collect();
    painter.add(egui::Shape::line(route, Stroke::new(2.0_f32, route_colour)));
    let marked = if stale { grey } else { LIT };
    let edited = if stale { " (before the last edit)" } else { "" };
    if let Some(at) = checked.caught_at() {
        ring(
            painter,
            projection,
            at,
            &format!("caught here{edited}"),
            marked,
        );
    }
    for &choke in &checked.chokepoints {
        ring(
            painter,
            projection,
            choke,
            &format!("lit, no way round{edited}"),
            marked,
        );
    }
}

/// Projects world points onto the view's rectangle on screen.
struct ViewProjection {
    projection: crate::render::camera::Projection,
    film: Vec2,
    rect: Rect,
}

impl ViewProjection {
    fn new(camera: &FlyCamera, view: &ViewState, rect: Rect) -> ViewProjection {
        ViewProjection {
            projection: crate::render::Camera::new(&camera.placement(), view.width, view.height)
                .projection(),
            film: Vec2::new(view.width as f32, view.height as f32),
            rect,
        }
    }

    fn point(&self, world: Vec3) -> Option<Pos2> {
        let film = self.projection.project(world.into())?;
        let fraction = film / self.film;
        Some(Pos2::new(
            self.rect.min.x + fraction.x * self.rect.width(),
            self.rect.min.y + fraction.y * self.rect.height(),
        ))
    }
}

/// Lines on the ground plane y = 0 every `step` metres around the point under the camera
/// (out to 12 m, or 40 steps, each way), the X axis red and the Z axis blue where they pass.
/// Each line is drawn in short pieces, so the part in front of the camera shows when the
/// rest is behind it, and a piece the level hides from the camera (`depth`) is left out.
fn ground_grid(
    painter: &egui::Painter,
    projection: &ViewProjection,
    eye: Vec3,
    step: f32,
    depth: Option<&crate::edit::camera::ViewDepth>,
) {
    let step = step.max(0.01);
    let reach = (12.0 / step).floor().clamp(1.0, 40.0);
    let centre = Vec3::new(
        (eye.x / step).round() * step,
        0.0,
        (eye.z / step).round() * step,
    );
    let span = reach * step;
    const PIECES: usize = 24;
    let faint = Stroke::new(1.0_f32, Color32::from_white_alpha(28));
    for index in -(reach as i32)..=reach as i32 {
        let offset = index as f32 * step;
        for (across, along) in [(Vec3::X, Vec3::Z), (Vec3::Z, Vec3::X)] {
            let at = centre + across * offset;
            let on_axis = (at.dot(across)).abs() < step * 0.5;
            let stroke = match (on_axis, across == Vec3::X) {
                // The line x = 0 runs along Z: the Z axis.
                (true, true) => Stroke::new(1.5_f32, Color32::from_rgb(70, 110, 230)),
                (true, false) => Stroke::new(1.5_f32, Color32::from_rgb(220, 70, 70)),
                _ => faint,
            };
            let point = |t: f32| at + along * (-span + 2.0 * span * t);
            for piece in 0..PIECES {
                let (a, b) = (
                    point(piece as f32 / PIECES as f32),
                    point((piece + 1) as f32 / PIECES as f32),
                );
                // A piece behind a wall or under a floor above the ground is hidden.
                let hidden = depth.is_some_and(|depth| !depth.shows((a + b) * 0.5));
                if let (false, Some(a), Some(b)) =
                    (hidden, projection.point(a), projection.point(b))
                {
                    painter.line_segment([a, b], stroke);
                }
            }
        }
    }
}

/// The twelve edges of the box [min, max], as far as they are in front of the camera.
fn draw_box(
    painter: &egui::Painter,
    projection: &ViewProjection,
    min: Vec3,
    max: Vec3,
    stroke: Stroke,
) {
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    for a in 0..8usize {
        for bit in [1, 2, 4] {
            if a & bit == 0
                && let (Some(p), Some(q)) = (
                    projection.point(corner(a)),
                    projection.point(corner(a | bit)),
                )
            {
                painter.line_segment([p, q], stroke);
            }
        }
    }
}

/// A warden's beat as it walks it: from where it stands through its route, and round.
fn beat_points(def: &EntityDef, warden: &WardenDef) -> Vec<Vec3> {
    let mut points = vec![def.transform.translation];
    points.extend(&warden.route);
    if let Some(first) = warden.route.first() {
        points.push(*first);
    }
    points
}

/// The colour and kind of the marker drawn for an entity that draws nothing.
fn marker_style(def: &EntityDef) -> (Color32, &'static str) {
    if let Some(light) = &def.light {
        let colour = match light {
            LightDef::Point { color, .. }
            | LightDef::Spot { color, .. }
            | LightDef::Directional { color, .. } => *color,
        };
        let c = (colour / colour.max_element().max(1e-6) * 255.0).to_array();
        return (
            Color32::from_rgb(c[0] as u8, c[1] as u8, c[2] as u8),
            "light",
        );
    }
    if def.player_spawn.is_some() {
        return (Color32::from_rgb(60, 220, 90), "player start");
    }
    if def.exit.is_some() {
        return (Color32::from_rgb(80, 160, 255), "exit");
    }
    if def.camera.is_some() {
        return (Color32::from_gray(170), "camera");
    }
    (Color32::from_gray(120), "entity")
}

/// The marker entity (one that draws nothing) under the screen point `at`.
fn marker_at(frame: &FrameInput, projection: &ViewProjection, at: Pos2) -> Option<LevelEntity> {
    frame
        .defs
        .iter()
        .filter(|(_, def)| def.instance.is_none())
        .filter_map(|(place, def)| {
            let seen = projection.point(def.transform.translation)?;
            let distance = seen.distance(at);
            (distance < HANDLE_RADIUS).then_some((distance, *place))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, place)| place)
}

/// A right-handed perspective projection onto depth 0..1 (wgpu's), looking down -Z: what
/// the gizmo projects its handles with, matching the renderer's pinhole camera.
fn perspective(yfov: f64, aspect: f64, near: f64) -> DMat4 {
    const FAR: f64 = 1000.0;
    let f = 1.0 / (0.5 * yfov).tan();
    let depth = FAR / (near - FAR);
    DMat4::from_cols_array(&[
        f / aspect,
        0.0,
        0.0,
        0.0,
        0.0,
        f,
        0.0,
        0.0,
        0.0,
        0.0,
        depth,
        -1.0,
        0.0,
        0.0,
        near * depth,
        0.0,
    ])
}

fn row_matrix(m: DMat4) -> mint::RowMatrix4<f64> {
    mint::RowMatrix4::from([
        m.row(0).to_array(),
        m.row(1).to_array(),
        m.row(2).to_array(),
        m.row(3).to_array(),
    ])
}

/// The audibility map over the floor: each place a warden would hear the noise made there
/// in orange, brighter the further over the threshold (20 dB and more at full); places
/// within its reach in the open that a wall keeps quiet in blue; each warden with its name
/// and the noise's reach in the open around it.
fn audibility_overlay(painter: &egui::Painter, map: &Audibility, projection: &ViewProjection) {
    let size = crate::edit::audibility::CELL;
    let mut mesh = egui::Mesh::default();
    let mut cell = |at: Vec3, colour: Color32| {
        let corner = at - Vec3::new(size * 0.5, 0.0, size * 0.5);
        floor_cell(&mut mesh, projection, corner, size, colour);
    };
    for &at in &map.muffled {
        cell(at, Color32::from_rgba_unmultiplied(40, 70, 160, 90));
    }
    for &(at, over_db, _) in &map.heard {
        let t = (over_db / 20.0).clamp(0.0, 1.0);
        let colour = Color32::from_rgba_unmultiplied(
            230,
            (170.0 - 120.0 * t) as u8,
            40,
            (90.0 + 80.0 * t) as u8,
        );
        cell(at, colour);
    }
    painter.add(mesh);
    for (name, feet) in &map.wardens {
        let reach: Vec<Pos2> = (0..=48)
            .filter_map(|i| {
                let angle = i as f32 / 48.0 * std::f32::consts::TAU;
                projection.point(
                    *feet
                        + Vec3::new(angle.cos(), 0.05, angle.sin())
                            * Vec3::new(map.radius, 1.0, map.radius),
                )
            })
            .collect();
        painter.add(egui::Shape::line(
            reach,
            Stroke::new(1.0_f32, Color32::from_rgba_unmultiplied(230, 120, 40, 160)),
        ));
        if let Some(at) = projection.point(*feet + Vec3::Y * 0.05) {
            painter.circle_filled(at, 6.0, Color32::from_rgb(230, 60, 60));
            painter.text(
                at + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                name,
                egui::FontId::proportional(13.0),
                Color32::WHITE,
            );
        }
    }
}

/// A map's cell on the floor: the square from `corner` (its minimum x and z, on the
/// floor) `size` metres along +x and +z, just above the floor, in `colour` (nothing when
/// a corner is behind the camera).
fn floor_cell(
    mesh: &mut egui::Mesh,
    projection: &ViewProjection,
    corner: Vec3,
    size: f32,
    colour: Color32,
) {
    let at = corner + Vec3::Y * 0.02;
    let corners = [
        at,
        at + Vec3::X * size,
        at + Vec3::new(size, 0.0, size),
        at + Vec3::Z * size,
    ];
    let Some(points) = corners
        .iter()
        .map(|&c| projection.point(c))
        .collect::<Option<Vec<Pos2>>>()
    else {
        return;
    };
    let first = mesh.vertices.len() as u32;
    for point in points {
        mesh.colored_vertex(point, colour);
    }
    mesh.add_triangle(first, first + 1, first + 2);
    mesh.add_triangle(first, first + 2, first + 3);
}
