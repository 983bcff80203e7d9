"""Widgets of the Main screen: they render what the screen gives them and post
intents (messages) up; none of them talks to the engine."""
