"""Navigation agents that play ObjectNav / InstNav episodes through the GLMap MCP server.

Every agent talks to the server only through an MCP client session (`agents.runner`):
in memory by default, or a stdio command / HTTP URL. `agents.runner.run_episode` plays one
benchmark episode and writes a JSONL trace of every tool call and an episode report.
"""
