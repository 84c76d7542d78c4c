"""Pure learning pieces: GAE, PopArt, PPO losses, discriminator loss/reward, normaliser."""
