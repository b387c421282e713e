//! The static world, logged once: walls, obstacles, surfaces and the true
//! occupancy map.

use rerun::RecordingStream;
use shoal_physics::{Arena, Obstacle};

/// Cell size of the logged occupancy map, metres.
const MAP_CELL_M: f64 = 0.05;

/// The arena's discs and boxes, grey.
fn log_obstacles(rec: &RecordingStream, arena: &Arena) -> rerun::RecordingStreamResult<()> {
    let (discs, boxes): (Vec<&Obstacle>, Vec<&Obstacle>) = arena
        .obstacles
        .iter()
        .partition(|o| matches!(o, Obstacle::Disc { .. }));
    let disc_centres: Vec<[f32; 2]> = discs
        .iter()
        .filter_map(|o| match o {
            Obstacle::Disc { center, .. } => Some([center[0] as f32, center[1] as f32]),
            Obstacle::Box { .. } => None,
        })
        .collect();
    let disc_radii: Vec<f32> = discs
        .iter()
        .filter_map(|o| match o {
            Obstacle::Disc { radius, .. } => Some(*radius as f32),
            Obstacle::Box { .. } => None,
        })
        .collect();
    rec.log_static(
        "world/arena/obstacles/discs",
        &rerun::Points2D::new(disc_centres)
            .with_radii(disc_radii)
            .with_colors([rerun::Color::from_rgb(120, 120, 120)]),
    )?;
    let (mins, sizes): (Vec<[f32; 2]>, Vec<[f32; 2]>) = boxes
        .iter()
        .filter_map(|o| match o {
            Obstacle::Box { min, max } => Some((
                [min[0] as f32, min[1] as f32],
                [(max[0] - min[0]) as f32, (max[1] - min[1]) as f32],
            )),
            Obstacle::Disc { .. } => None,
        })
        .unzip();
    rec.log_static(
        "world/arena/obstacles/boxes",
        &rerun::Boxes2D::from_mins_and_sizes(mins, sizes)
            .with_colors([rerun::Color::from_rgb(120, 120, 120)]),
    )?;
    Ok(())
}

/// The arena's surfaces as labelled boxes under everything else.
fn log_surfaces(rec: &RecordingStream, arena: &Arena) -> rerun::RecordingStreamResult<()> {
    let (mins, sizes): (Vec<[f32; 2]>, Vec<[f32; 2]>) = arena
        .surfaces
        .iter()
        .map(|s| {
            (
                [s.region[0] as f32, s.region[1] as f32],
                [
                    (s.region[2] - s.region[0]) as f32,
                    (s.region[3] - s.region[1]) as f32,
                ],
            )
        })
        .unzip();
    let labels: Vec<String> = arena.surfaces.iter().map(|s| s.name.clone()).collect();
    rec.log_static(
        "world/arena/surfaces",
        &rerun::Boxes2D::from_mins_and_sizes(mins, sizes)
            .with_labels(labels)
            .with_draw_order(-10.0),
    )?;
    Ok(())
}

pub fn log_arena(rec: &RecordingStream, arena: &Arena) -> rerun::RecordingStreamResult<()> {
    let walls: Vec<Vec<[f32; 2]>> = arena
        .all_walls()
        .map(|w| {
            vec![
                [w.from[0] as f32, w.from[1] as f32],
                [w.to[0] as f32, w.to[1] as f32],
            ]
        })
        .collect();
    rec.log_static(
        "world/arena/walls",
        &rerun::LineStrips2D::new(walls).with_colors([rerun::Color::from_rgb(200, 200, 200)]),
    )?;

    log_obstacles(rec, arena)?;
    log_surfaces(rec, arena)?;
    let (width, height, cells) = occupancy(arena);
    rec.log_static(
        "world/arena/map",
        &rerun::GridMap::new(
            cells,
            rerun::components::ImageFormat::from_color_model(
                [width as u32, height as u32],
                rerun::ColorModel::L,
                rerun::ChannelDatatype::U8,
            ),
            MAP_CELL_M as f32,
        )
        .with_colormap(rerun::components::Colormap::RvizMap)
        .with_draw_order(-20.0),
    )?;
    Ok(())
}

/// The arena rasterised with ROS occupancy values: 0 free, 100 occupied.
pub fn occupancy(arena: &Arena) -> (usize, usize, Vec<u8>) {
    let width = (arena.width / MAP_CELL_M).ceil() as usize;
    let height = (arena.height / MAP_CELL_M).ceil() as usize;
    let mut cells = vec![0u8; width * height];
    let half = MAP_CELL_M / 2.0;
    for row in 0..height {
        for col in 0..width {
            let p = glam::DVec2::new(
                (col as f64 + 0.5) * MAP_CELL_M,
                (row as f64 + 0.5) * MAP_CELL_M,
            );
            let on_wall = arena.all_walls().any(|w| {
                shoal_physics::arena::distance_to_segment(p, w.from.into(), w.to.into()) <= half
            });
            if on_wall || arena.obstacles.iter().any(|o| o.distance(p) <= 0.0) {
                cells[row * width + col] = 100;
            }
        }
    }
    (width, height, cells)
}
