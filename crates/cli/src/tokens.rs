//! `kiln tokens`: the admin issues, lists and revokes a coordinator's tokens (submitters'
//! and workers' credentials). A new token's secret is printed once, on stdout alone, so it
//! can be piped into a secret store; the coordinator keeps only its hash.

use anyhow::Result;
use kiln_farm::api::{Role, TokenInfo, TokenRequest};
use kiln_farm::client::Client;

#[derive(clap::Args)]
pub struct TokensArgs {
    #[command(subcommand)]
    action: TokenAction,
    #[arg(long, default_value = "http://127.0.0.1:7878", global = true)]
    coordinator: String,
    /// The admin's token (the coordinator's --token).
    #[arg(long, env = "KILN_TOKEN", global = true)]
    token: Option<String>,
    /// The API's JSON rather than text.
    #[arg(long, global = true)]
    json: bool,
}

#[derive(clap::Subcommand)]
enum TokenAction {
    /// Issue a token: a submitter's (submits, sees and cancels its own jobs) or a worker's
    /// credential (leases, heartbeats and uploads under its name only). Prints the secret.
    Create {
        /// submitter, worker or admin.
        #[arg(long, value_parser = parse_role)]
        role: Role,
        /// Whose it is: the submitter's name, or the worker's (its --name).
        #[arg(long)]
        name: String,
    },
    /// List the tokens issued (never their secrets).
    List,
    /// Revoke a token: refused from its next request on; a worker's leases are lent again.
    Revoke {
        /// The token's id (from `kiln tokens list`).
        id: u64,
    },
}

fn parse_role(s: &str) -> std::result::Result<Role, String> {
    match s {
        "admin" => Ok(Role::Admin),
        "submitter" => Ok(Role::Submitter),
        "worker" => Ok(Role::Worker),
        other => Err(format!(
            "unknown role '{other}' (known: submitter, worker, admin)"
        )),
    }
}

pub fn run(args: TokensArgs) -> Result<()> {
    let client = Client::new(&args.coordinator, args.token.clone());
    let rt = crate::farm::runtime()?;
    match args.action {
        TokenAction::Create { role, name } => {
            let issued = rt.block_on(client.issue_token(&TokenRequest { role, name }))?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&issued)?);
            } else {
                eprintln!(
                    "kiln tokens: token {} for {} {} (shown once; the coordinator keeps its hash):",
                    issued.info.id,
                    issued.info.role.as_str(),
                    issued.info.name
                );
                println!("{}", issued.token);
            }
        }
        TokenAction::List => {
            let all = rt.block_on(client.tokens())?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&all)?);
            } else {
                let rows = all.iter().map(row).collect();
                crate::listing::print_table(&["ID", "ROLE", "NAME", "STATE"], rows);
            }
        }
        TokenAction::Revoke { id } => {
            let t = rt.block_on(client.revoke_token(id))?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&t)?);
            } else {
                println!("token {} ({} {}) is revoked", t.id, t.role.as_str(), t.name);
            }
        }
    }
    Ok(())
}

fn row(t: &TokenInfo) -> Vec<String> {
    vec![
        t.id.to_string(),
        t.role.as_str().to_string(),
        t.name.clone(),
        if t.revoked { "revoked" } else { "valid" }.to_string(),
    ]
}
