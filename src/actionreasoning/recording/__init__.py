"""What a trial leaves to look at: snapshots, videos (filmed in a process of their own)
and Rerun recordings, each a trial observer."""
