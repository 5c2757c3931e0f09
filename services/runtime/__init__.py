"""Process runtime shared by every service: Zenoh transport and lifecycle (signals, deadlines)."""
