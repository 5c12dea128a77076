//! A kept file opened to be sent: what the data directory hands out and `http.rs` streams,
//! so that the HTTP layer never names a path and no download is read into memory whole.

use std::path::Path;

/// A kept file opened to be sent: its handle (which reads the file as it was when opened,
/// whatever is renamed over it since) and its length.
pub struct Stored {
    pub file: tokio::fs::File,
    pub len: u64,
}

impl Stored {
    /// Opens `path`, or says why not.
    pub async fn open(path: &Path) -> std::io::Result<Stored> {
        let file = tokio::fs::File::open(path).await?;
        let len = file.metadata().await?.len();
        Ok(Stored { file, len })
    }

    /// All its bytes (for tests, which look at what a client would get).
    #[cfg(test)]
    pub async fn bytes(mut self) -> std::io::Result<Vec<u8>> {
        use tokio::io::AsyncReadExt;
        let mut bytes = Vec::new();
        self.file.read_to_end(&mut bytes).await?;
        Ok(bytes)
    }
}
