"""cassie_flip_sim."""
