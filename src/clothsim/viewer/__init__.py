"""The interactive viewer: a window with the cloth, a Dear ImGui panel and mouse/key controls."""
