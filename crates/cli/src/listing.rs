//! `kiln jobs` and `kiln workers`: a coordinator's jobs and workers as tables for people,
//! or as the API's JSON (`--json`) for scripts.

use anyhow::Result;
use kiln_farm::api::{JobStatus, WorkerStatus};
use kiln_farm::client::Client;

#[derive(clap::Args)]
pub struct ListArgs {
    #[arg(long, default_value = "http://127.0.0.1:7878")]
    coordinator: String,
    #[arg(long, env = "KILN_TOKEN")]
    token: Option<String>,
    /// The API's JSON, one array, rather than a table.
    #[arg(long)]
    json: bool,
}

pub fn jobs(args: ListArgs) -> Result<()> {
    let client = Client::new(&args.coordinator, args.token.clone());
    let jobs = crate::farm::runtime()?.block_on(client.jobs())?;
    let header = [
        "JOB", "STATE", "FRAMES", "PROGRESS", "SPP", "PASSES", "PRIORITY", "NOTE",
    ];
    list(&args, &jobs, &header, job_row)
}

fn job_row(j: &JobStatus) -> Vec<String> {
    let last = j.passes.last().copied().unwrap_or(0);
    let note = j
        .error
        .clone()
        .or_else(|| j.waiting.clone())
        .or_else(|| j.notice.clone())
        .unwrap_or_default();
    vec![
        j.id.to_string(),
        j.state.as_str().to_string(),
        j.frame_count.to_string(),
        format!("{:.0}%", j.progress * 100.0),
        format!("{}/{last}", j.samples_per_pixel_done),
        format!("{}/{}", j.passes_done, j.passes.len()),
        j.priority.to_string(),
        note,
    ]
}

pub fn workers(args: ListArgs) -> Result<()> {
    let client = Client::new(&args.coordinator, args.token.clone());
    let workers = crate::farm::runtime()?.block_on(client.workers())?;
    let header = [
        "WORKER",
        "RENDERING",
        "TILES",
        "FAILURES",
        "HEARD",
        "TAGS",
        "MESHES",
        "SET ASIDE",
    ];
    list(&args, &workers, &header, worker_row)
}

/// `items` as the API's JSON with `--json`, else as a table of `header` and their rows.
fn list<T: serde::Serialize>(
    args: &ListArgs,
    items: &[T],
    header: &[&str],
    row: impl Fn(&T) -> Vec<String>,
) -> Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(items)?);
    } else {
        print_table(header, items.iter().map(row).collect());
    }
    Ok(())
}

fn worker_row(w: &WorkerStatus) -> Vec<String> {
    let rendering = match w.leases.as_slice() {
        [] => "idle".to_string(),
        [l] if l.frame > 0 => format!("job {} frame {} tile {}", l.job, l.frame + 1, l.tile_index),
        [l] => format!("job {} tile {}", l.job, l.tile_index),
        ls => format!("job {} ({} tiles)", ls[0].job, ls.len()),
    };
    vec![
        w.name.clone(),
        rendering,
        w.tiles_done.to_string(),
        w.failures.to_string(),
        w.last_seen_seconds
            .map_or("never".into(), |s| format!("{s:.0} s ago")),
        w.tags.join(","),
        w.geometry.map_or(String::new(), |g| {
            format!("{} read, {} reused", g.loads, g.reused)
        }),
        w.set_aside.clone().unwrap_or_default(),
    ]
}

/// Columns padded to their widest cell, the last left ragged.
pub(crate) fn print_table(header: &[&str], rows: Vec<Vec<String>>) {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in &rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: Vec<String>| {
        let last = cells.len() - 1;
        let text: Vec<String> = cells
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                if i == last {
                    c
                } else {
                    format!("{c:<w$}", w = widths[i])
                }
            })
            .collect();
        println!("{}", text.join("  ").trim_end());
    };
    line(header.iter().map(|h| h.to_string()).collect());
    for row in rows {
        line(row);
    }
}
