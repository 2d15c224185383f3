//! A cleaning report as a person reads it: one row per thing the cleaning
//! did, in words, with the measured values rounded to what they mean.

use morphoid_core::clean::CleanReport;

/// The rows of the report's cleaning table: `(what, how)`, only the steps
/// that did something beside the sizes in and out.
pub(super) fn cleaning_rows(r: &CleanReport) -> Vec<(&'static str, String)> {
    let mut rows = vec![
        (
            "input",
            format!("{} vertices, {} faces", r.input_vertices, r.input_faces),
        ),
        (
            "output",
            format!(
                "{} vertices, {} faces, {} boundary loop(s), Euler characteristic {}",
                r.output_vertices, r.output_faces, r.boundary_loops, r.euler_characteristic
            ),
        ),
        (
            "size",
            format!(
                "area {:.4}, bounding-box diagonal {:.4} (file units)",
                r.area, r.bbox_diagonal
            ),
        ),
    ];
    if r.triangulated_point_cloud {
        rows.push((
            "point cloud",
            "a surface reconstructed from the points".into(),
        ));
    }
    if r.predecimated_faces > 0 {
        rows.push((
            "decimated",
            format!("to {} faces before cleaning", r.predecimated_faces),
        ));
    }
    let repairs: Vec<String> = [
        (r.welded_vertices, "vertices welded"),
        (r.removed_faces, "degenerate or duplicate faces removed"),
        (r.dropped_components, "small components dropped"),
        (r.filled_holes, "holes filled"),
        (r.repaired_nonmanifold_edges, "non-manifold edges repaired"),
        (
            r.repaired_nonmanifold_vertices,
            "non-manifold vertices repaired",
        ),
        (r.flipped_faces, "faces turned to agree"),
        (r.edge_flips, "edges flipped for the disk map"),
    ]
    .iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, what)| format!("{n} {what}"))
    .collect();
    if !repairs.is_empty() || r.reversed_orientation {
        let mut text = repairs.join(", ");
        if r.reversed_orientation {
            if !text.is_empty() {
                text.push_str("; ");
            }
            text.push_str("orientation reversed");
        }
        rows.push(("repairs", text));
    }
    if let Some(c) = &r.crown {
        rows.push((
            "crown",
            format!(
                "cut from a closed whole tooth ({}{}) at {:.0}–{:.0} % of its length (mean {:.0} %), \
                 crease {:.0}°; kept area {:.4}, removed {:.4} ({} faces); {} holes filled, {} handles removed",
                c.method,
                if c.revoxelized {
                    ", after a voxel grid closed its handles"
                } else {
                    ""
                },
                100.0 * c.cut_height_min,
                100.0 * c.cut_height_max,
                100.0 * c.cut_height_mean,
                c.crease_degrees,
                c.kept_area,
                c.removed_area,
                c.removed_faces,
                c.filled_holes,
                c.removed_handles
            ),
        ));
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_steps_that_did_something_get_a_row() {
        let mut r = CleanReport {
            input_vertices: 10,
            input_faces: 16,
            output_vertices: 9,
            output_faces: 14,
            boundary_loops: 1,
            euler_characteristic: 1,
            area: 1.0,
            bbox_diagonal: 2.0,
            ..CleanReport::default()
        };
        let names = |r: &CleanReport| cleaning_rows(r).iter().map(|(k, _)| *k).collect::<Vec<_>>();
        assert_eq!(names(&r), ["input", "output", "size"]);
        r.welded_vertices = 3;
        r.reversed_orientation = true;
        let rows = cleaning_rows(&r);
        assert_eq!(
            rows[3],
            (
                "repairs",
                "3 vertices welded; orientation reversed".to_string()
            )
        );
    }
}
