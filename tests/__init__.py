"""footopt tests (a package, so helper modules import as tests.*)."""
